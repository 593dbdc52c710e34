"""Training index: `nuparquet index OUT --info-version 2` vs the devkit-based loop mmdetection3d's converter runs.

    .venv/bin/python benchmarks/bench_index.py [--scenes 850] [--loop-samples 200]

Ours: a fresh process running the CLI on the cached synthetic set (wall time, peak RSS). Reference, in the same
run: a fresh process that does what `create_data.py nuscenes` + `update_infos_to_v2.py` do per sample with the
devkit — `NuScenes(version, dataroot)` (timed in full), then for `--loop-samples` samples the converter's
per-sample work reimplemented faithfully (get_sample_data of the lidar and of each camera, obtain_sensor2top
for 6 cameras and 10 sweeps, box_velocity per box; then update_infos_to_v2's 4x4 matrices, lidar2cam and
lidar2sensor, and per camera the get_nuscenes_2d_boxes projection with its shapely clipping); the loop
time is extrapolated linearly to every sample (stated as such in the row). `--scenes 850` is trainval scale
(the default cache of bench_data.py); a smaller `--scenes` builds its own cached set. Prints its row (7) and writes
benchmarks/results/<UTC time>-index.json; `run_all.py` runs it as `index`.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

TARGET_RATIO = 15.0
TARGET_RSS_MB = 4096.0
CAMERAS = ("CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_FRONT_LEFT", "CAM_BACK", "CAM_BACK_LEFT", "CAM_BACK_RIGHT")


def devkit_child(dataroot: str, version: str, loop_samples: int) -> None:
    import numpy as np
    from nuscenes.nuscenes import NuScenes
    from nuscenes.utils.geometry_utils import view_points
    from pyquaternion import Quaternion
    from shapely.geometry import MultiPoint, box

    start, start_cpu = time.perf_counter(), time.process_time()
    nusc = NuScenes(version=version, dataroot=dataroot, verbose=False)
    loaded, loaded_cpu = time.perf_counter(), time.process_time()

    def sensor2top(token, l2e_t, l2e_r_mat, e2g_t, e2g_r_mat):
        sd = nusc.get("sample_data", token)
        cs = nusc.get("calibrated_sensor", sd["calibrated_sensor_token"])
        pose = nusc.get("ego_pose", sd["ego_pose_token"])
        l2e_r_s_mat = Quaternion(cs["rotation"]).rotation_matrix
        e2g_r_s_mat = Quaternion(pose["rotation"]).rotation_matrix
        back = np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(l2e_r_mat).T
        r = (l2e_r_s_mat.T @ e2g_r_s_mat.T) @ back
        t = (np.array(cs["translation"]) @ e2g_r_s_mat.T + pose["translation"]) @ back
        t -= np.array(e2g_t) @ back + np.array(l2e_t) @ np.linalg.inv(l2e_r_mat).T
        return r.T, t

    def to_matrix(rotation, translation):  # update_infos_to_v2.convert_quaternion_to_matrix
        result = np.eye(4)
        result[:3, :3] = Quaternion(rotation).rotation_matrix
        result[:3, 3] = np.array(translation)
        return result.astype(np.float32).tolist()

    def lidar2sensor(rot, trans):  # update_infos_to_v2: lidar2cam / lidar2sensor
        out = np.eye(4)
        out[:3, :3] = rot.T
        out[:3, 3:4] = -1 * np.matmul(rot.T, trans.reshape(3, 1))
        return out.astype(np.float32).tolist()

    samples = nusc.sample[:loop_samples]
    for sample in samples:
        sd = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
        cs = nusc.get("calibrated_sensor", sd["calibrated_sensor_token"])
        pose = nusc.get("ego_pose", sd["ego_pose_token"])
        _, boxes, _ = nusc.get_sample_data(sd["token"])
        l2e_r_mat = Quaternion(cs["rotation"]).rotation_matrix
        e2g_r_mat = Quaternion(pose["rotation"]).rotation_matrix
        cams = {}
        for cam in CAMERAS:
            nusc.get_sample_data(sample["data"][cam])  # create_nuscenes_infos: cam_path, _, cam_intrinsic = ...
            cams[cam] = sensor2top(sample["data"][cam], cs["translation"], l2e_r_mat, pose["translation"], e2g_r_mat)
        rec, sweeps = sd, []
        while len(sweeps) < 10 and rec["prev"]:
            prev = nusc.get("sample_data", rec["prev"])
            sweeps.append((prev, sensor2top(rec["prev"], cs["translation"], l2e_r_mat, pose["translation"],
                                            e2g_r_mat)))
            rec = prev
        # update_infos_to_v2: every 4x4 (convert_quaternion_to_matrix), lidar2cam / lidar2sensor, instances
        to_matrix(pose["rotation"], pose["translation"])
        to_matrix(cs["rotation"], cs["translation"])
        for cam in CAMERAS:
            cam_sd = nusc.get("sample_data", sample["data"][cam])
            cam_cs = nusc.get("calibrated_sensor", cam_sd["calibrated_sensor_token"])
            to_matrix(cam_cs["rotation"], cam_cs["translation"])
            lidar2sensor(*cams[cam])
        for prev, transform in sweeps:
            sweep_pose = nusc.get("ego_pose", prev["ego_pose_token"])
            sweep_cs = nusc.get("calibrated_sensor", prev["calibrated_sensor_token"])
            to_matrix(sweep_pose["rotation"], sweep_pose["translation"])
            to_matrix(sweep_cs["rotation"], sweep_cs["translation"])
            lidar2sensor(*transform)
        for b in boxes:
            b.orientation.yaw_pitch_roll
        for token in sample["anns"]:
            np.array([*nusc.box_velocity(token)[:2], 0.0]) @ np.linalg.inv(e2g_r_mat).T @ np.linalg.inv(l2e_r_mat).T
        for cam in CAMERAS:  # get_nuscenes_2d_boxes
            cam_sd = nusc.get("sample_data", sample["data"][cam])
            cam_cs = nusc.get("calibrated_sensor", cam_sd["calibrated_sensor_token"])
            cam_pose = nusc.get("ego_pose", cam_sd["ego_pose_token"])
            k = np.array(cam_cs["camera_intrinsic"])
            for token in sample["anns"]:
                b = nusc.get_box(token)
                b.translate(-np.array(cam_pose["translation"]))
                b.rotate(Quaternion(cam_pose["rotation"]).inverse)
                b.translate(-np.array(cam_cs["translation"]))
                b.rotate(Quaternion(cam_cs["rotation"]).inverse)
                corners = b.corners()
                corners = corners[:, corners[2] > 0]
                hull = MultiPoint(view_points(corners, k, True).T[:, :2].tolist()).convex_hull
                canvas = box(0, 0, 1600, 900)
                if hull.intersects(canvas):
                    hull.intersection(canvas)
                nusc.box_velocity(token)
    done, done_cpu = time.perf_counter(), time.process_time()
    per_sample = (done - loaded) / max(len(samples), 1)
    per_sample_cpu = (done_cpu - loaded_cpu) / max(len(samples), 1)
    print(json.dumps({"load_s": loaded - start, "loop_per_sample_s": per_sample, "samples": len(nusc.sample),
                      "extrapolated_s": (loaded - start) + per_sample * len(nusc.sample),
                      "load_cpu_s": loaded_cpu - start_cpu, "loop_per_sample_cpu_s": per_sample_cpu,
                      "extrapolated_cpu_s": (loaded_cpu - start_cpu) + per_sample_cpu * len(nusc.sample)}))


def run(repeats: int = 3, scenes: int = 850, loop_samples: int = 200) -> dict:
    """Row 7: `nuparquet index` against the devkit loop (its per-sample part sampled and extrapolated)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_data as datasets
    from harness import Row, log, megabytes, python_child, repeat, run_child, seconds, summarize

    version = datasets.TRAINVAL_VERSION
    if scenes == datasets.TRAINVAL_SCENES:
        root, out = datasets.trainval_root(), datasets.trainval_out()
    else:
        root = datasets._synth(datasets.CACHE / f"index-{scenes}", scenes, version, with_images=False)
        out = datasets._convert(root, version, datasets.CACHE / f"index-{scenes}-out")
    log(f"row 7: nuparquet index ({scenes} scenes) vs the devkit loop")
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [*datasets.NUPARQUET, "index", str(out), "--out", tmp, "--version", "v1.0-trainval",
               "--info-version", "2", "--quiet"]
        ours = summarize(repeat(cmd, repeats, label="nuparquet index v2"))
        command = " ".join(map(str, cmd)).replace(tmp, "TMP")
    log("  devkit loop (load + sampled per-sample loop, extrapolated)")
    devkit_cmd = python_child(__file__, "--devkit-child", root, version, loop_samples)
    ref = run_child(devkit_cmd).report
    ratio = ref["extrapolated_s"] / ours["wall_s"]
    # CPU seconds as well: on a shared, loaded box the two wall times are taken minutes apart
    ratio_cpu = ref["extrapolated_cpu_s"] / ours["cpu_s"]
    met = ratio >= TARGET_RATIO and ours["max_rss_mb"] <= TARGET_RSS_MB
    result = {"scenes": scenes, "samples": ref["samples"], "ours_wall_s": ours["wall_s"],
              "ours_cpu_s": ours["cpu_s"], "ours_max_rss_mb": ours["max_rss_mb"], "devkit_load_s": ref["load_s"],
              "devkit_loop_per_sample_s": ref["loop_per_sample_s"], "devkit_extrapolated_s": ref["extrapolated_s"],
              "devkit_load_cpu_s": ref["load_cpu_s"], "devkit_loop_per_sample_cpu_s": ref["loop_per_sample_cpu_s"],
              "devkit_extrapolated_cpu_s": ref["extrapolated_cpu_s"], "ratio": ratio, "ratio_cpu": ratio_cpu,
              "met": met}
    row = Row(
        id="7",
        benchmark=f"`nuparquet index --info-version 2` on {scenes} scenes ({ref['samples']:,} samples: v2 pickles "
        "train + val and infos/ Parquet)",
        ours=f"{seconds(ours['wall_s'])} ({seconds(ours['cpu_s'])} CPU), {megabytes(ours['max_rss_mb'])} peak",
        reference=f"devkit load {seconds(ref['load_s'])} + the converter's per-sample loop "
        f"{ref['loop_per_sample_s'] * 1000:.1f} ms/sample x {ref['samples']:,} (first {loop_samples} timed, "
        f"extrapolated): {seconds(ref['extrapolated_s'])}",
        ratio=f"{ratio:.1f}x (CPU {ratio_cpu:.1f}x)",
        target=f"≥ {TARGET_RATIO:.0f}x, ≤ {TARGET_RSS_MB / 1024:.0f} GB",
        met=met,
    )
    return {"name": "index", "command": command,
            "devkit": {"command": " ".join(map(str, devkit_cmd))}, **result, "rows": [row]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=850)
    parser.add_argument("--loop-samples", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--devkit-child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.devkit_child:
        devkit_child(args.devkit_child[0], args.devkit_child[1], int(args.devkit_child[2]))
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from harness import report_alone

    report_alone(run(args.repeats, args.scenes, args.loop_samples))


if __name__ == "__main__":
    main()
