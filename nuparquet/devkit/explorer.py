"""`NuScenesExplorer`: the devkit's printers (`list_*`, `get_sample_lidarseg_stats`) and its one data call
(`map_pointcloud_to_image`) over a `nuparquet.devkit.NuScenes`; its renderers (`devkit.renders`) draw with
`nuparquet.rendering.pictures.single`.

The printers print what the devkit prints, character for character. The two that walk every annotation
(`list_categories`, `list_attributes`) read the few columns they need instead of building a million records:
they answer from the converted data, not from records a user may have changed. One module, as the devkit's
explorer is one class: most of its length is the printers' exact formats.

Longer than our ~300-line norm on purpose: it mirrors a devkit module whose whole surface user code calls, so its
pieces stay where the devkit's users look for them.
"""

from __future__ import annotations

import os
import os.path as osp
import time
from datetime import datetime, timezone

import numpy as np
from pyquaternion import Quaternion

from nuparquet.devkit import labels
from nuparquet.devkit.columns import fixed_block, single_chunk, token_bytes
from nuparquet.devkit.errors import NotServed
from nuparquet.devkit.renders import ExplorerRenders
from nuparquet.devkit.utils.data_classes import LidarPointCloud, RadarPointCloud
from nuparquet.devkit.utils.data_io import load_bin_file
from nuparquet.devkit.utils.geometry_utils import view_points

class NuScenesExplorer(ExplorerRenders):
    """The devkit's explorer over `nusc` (a `nuparquet.devkit.NuScenes`); its renderers are `devkit.renders`."""

    def __init__(self, nusc):
        self.nusc = nusc

    def get_color(self, category_name: str) -> tuple[int, int, int]:
        return self.nusc.colormap[category_name]

    # --- printers -------------------------------------------------------------------------------------------

    def list_categories(self) -> None:
        """Per category: annotations, and the mean and deviation of width, length, height and length / width."""
        nusc = self.nusc
        print("Category stats for split %s:" % nusc.version)
        if not len(nusc.sample_annotation):
            return
        names = nusc._index.annotation_categories()
        sizes = _numpy_column(nusc._source.read("sample_annotation", ["size"]).column("size"))
        for name in sorted(set(names.tolist())):
            rows = np.flatnonzero(names == name)
            stats = np.empty((len(rows), 4))
            stats[:, :3] = sizes[rows]
            stats[:, 3] = sizes[rows, 1] / sizes[rows, 0]
            print("{:27} n={:5}, width={:5.2f}\u00B1{:.2f}, len={:5.2f}\u00B1{:.2f}, height={:5.2f}\u00B1{:.2f}, "
                  "lw_aspect={:5.2f}\u00B1{:.2f}".format(name[:27], stats.shape[0],
                                                          np.mean(stats[:, 0]), np.std(stats[:, 0]),
                                                          np.mean(stats[:, 1]), np.std(stats[:, 1]),
                                                          np.mean(stats[:, 2]), np.std(stats[:, 2]),
                                                          np.mean(stats[:, 3]), np.std(stats[:, 3])))

    def list_attributes(self) -> None:
        """Annotations per attribute name, by name."""
        nusc = self.nusc
        if not len(nusc.sample_annotation):
            return
        column = nusc._source.read("sample_annotation", ["attribute_tokens"]).column("attribute_tokens")
        tokens = single_chunk(column).flatten()
        counts: dict[str, int] = {}
        if len(tokens):
            values, number = np.unique(token_bytes(tokens), return_counts=True)
            for token, count in zip(values.tolist(), number.tolist()):
                name = nusc.get("attribute", token.decode())["name"]
                counts[name] = counts.get(name, 0) + count
        for name, count in sorted(counts.items()):
            print("{}: {}".format(name, count))

    def list_scenes(self) -> None:
        """Every scene by start time: name and description, start, duration, location, annotations (the
        devkit's count: every sample but the last)."""
        nusc = self.nusc

        def ann_count(record):
            count = 0
            sample = nusc.get("sample", record["first_sample_token"])
            while not sample["next"] == "":
                count += len(sample["anns"])
                sample = nusc.get("sample", sample["next"])
            return count

        recs = [(nusc.get("sample", record["first_sample_token"])["timestamp"], record) for record in nusc.scene]
        for start_time, record in sorted(recs):
            start_time = nusc.get("sample", record["first_sample_token"])["timestamp"] / 1000000
            length_time = nusc.get("sample", record["last_sample_token"])["timestamp"] / 1000000 - start_time
            location = nusc.get("log", record["log_token"])["location"]
            desc = record["name"] + ", " + record["description"]
            if len(desc) > 55:
                desc = desc[:51] + "..."
            if len(location) > 18:
                location = location[:18]
            started = datetime.fromtimestamp(start_time, timezone.utc).strftime("%y-%m-%d %H:%M:%S")
            print("{:16} [{}] {:4.0f}s, {}, #anns:{}".format(desc, started, length_time, location, ann_count(record)))

    def list_sample(self, sample_token: str) -> None:
        """The sample's sample_data and annotation tokens."""
        nusc = self.nusc
        sample_record = nusc.get("sample", sample_token)
        print("Sample: {}\n".format(sample_record["token"]))
        for sd_token in sample_record["data"].values():
            sd_record = nusc.get("sample_data", sd_token)
            print("sample_data_token: {}, mod: {}, channel: {}".format(sd_token, sd_record["sensor_modality"],
                                                                       sd_record["channel"]))
        print("")
        for ann_token in sample_record["anns"]:
            ann_record = nusc.get("sample_annotation", ann_token)
            print("sample_annotation_token: {}, category: {}".format(ann_record["token"], ann_record["category_name"]))

    def list_lidarseg_categories(self, sort_by: str = "count", gt_from: str = "lidarseg") -> None:
        """Points per lidarseg class over every labelled frame, sorted by count, name or index."""
        nusc = self.nusc
        assert gt_from in ["lidarseg", "panoptic"], f"gt_from can only be lidarseg or panoptic, get {gt_from}"
        _needs_labels(nusc, gt_from)
        assert sort_by in ["count", "name", "index"], \
            "Error: sort_by can only be one of the following: count / name / index."
        print(f"Calculating semantic point stats for nuScenes-{gt_from}...")
        semantic_table = getattr(nusc, gt_from)
        start_time = time.time()
        lidarseg_counts = [0] * len(nusc.lidarseg_idx2name_mapping)
        tokens = [record["sample_data_token"] for record in semantic_table]
        for points_label in labels.frame_labels(nusc, gt_from, tokens):
            indices = labels.class_counts(points_label, gt_from)
            ii = np.nonzero(indices)[0]
            for class_idx, class_count in zip(ii, indices[ii]):
                lidarseg_counts[class_idx] += class_count
        counts = {nusc.lidarseg_idx2name_mapping[i]: lidarseg_counts[i] for i in range(len(lidarseg_counts))}
        total_count = 0
        for class_name, count in _sorted_counts(counts, sort_by):
            idx = nusc.lidarseg_name2idx_mapping[class_name]
            print("{:3}  {:40} nbr_points={:12,}".format(idx, class_name, count))
            total_count += count
        print("Calculated stats for {} point clouds in {:.1f} seconds, total {} points.\n=====".format(
            len(semantic_table), time.time() - start_time, total_count))

    def list_panoptic_instances(self, sort_by: str = "count", get_hist: bool = False) -> None:
        """Instances per frame, and per thing class the instances, frames per instance and points per instance."""
        nusc = self.nusc
        _needs_labels(nusc, "panoptic")
        assert sort_by in ["count", "name", "index"], \
            "Error: sort_by can only be one of the following: count / name / index."
        print("Calculating instance stats for nuScenes-panoptic ...")
        start_time = time.time()
        records = list(nusc.panoptic)
        frame_labels = labels.frame_labels(nusc, "panoptic", [r["sample_data_token"] for r in records])
        scenes = [nusc.get("sample", nusc.get("sample_data", r["sample_data_token"])["sample_token"])["scene_token"]
                  for r in records]
        stats = labels.panoptic_instance_stats(list(zip(scenes, frame_labels)), nusc.lidarseg_idx2name_mapping,
                                               get_hist)
        pm = "\u00B1"
        frame_num_insts = stats["per_frame_panoptic_stats"]["per_frame_num_instances"]
        print("Per-frame number of instances: {:.0f}{}{:.0f}".format(frame_num_insts[0], pm, frame_num_insts[1]))
        instance_counts = stats["per_category_panoptic_stats"].copy()
        if sort_by == "count":
            instance_counts = sorted(instance_counts.items(), key=lambda item: item[1]["num_instances"], reverse=True)
        elif sort_by == "name":
            instance_counts = sorted(instance_counts.items())
        else:
            instance_counts = list(instance_counts.items())
        print("Per-category instance stats:")
        for cat_name, s in instance_counts:
            print("{}: {} instances, each instance spans to {:.0f}{}{:.0f} frames, with {:.0f}{}{:.0f} points".format(
                cat_name, s["num_instances"], s["num_frames_per_instance"][0], pm, s["num_frames_per_instance"][1],
                s["num_points_per_instance"][0], pm, s["num_points_per_instance"][1]))
        print("\nCalculated stats for {} point clouds in {:.1f} seconds, total {} instances, {} sample annotations."
              "\n=====".format(len(records), time.time() - start_time, stats["num_instances"],
                              stats["num_sample_annotations"]))

    def sample_lidarseg_stats(self, sample_token: str, sort_by: str = "count", lidarseg_preds_bin_path: str = None,
                              gt_from: str = "lidarseg") -> None:
        """`NuScenes.get_sample_lidarseg_stats`: points per class in one sample's LIDAR_TOP frame."""
        nusc = self.nusc
        assert gt_from in ["lidarseg", "panoptic"], f"gt_from can only be lidarseg or panoptic, get {gt_from}"
        _needs_labels(nusc, gt_from)
        assert sort_by in ["count", "name", "index"], \
            "Error: sort_by can only be one of the following: count / name / index."
        semantic_table = getattr(nusc, gt_from)
        ref_sd_token = nusc.get("sample", sample_token)["data"]["LIDAR_TOP"]
        ref_sd_record = nusc.get("sample_data", ref_sd_token)
        assert ref_sd_record["is_key_frame"], \
            "Error: Only pointclouds which are keyframes have lidar segmentation labels. Rendering aborted."
        if lidarseg_preds_bin_path:
            assert os.path.exists(lidarseg_preds_bin_path), (
                "Error: Unable to find {} to load the predictions for sample token {} (lidar sample data token {}) "
                "from.".format(lidarseg_preds_bin_path, sample_token, ref_sd_token))
            header = "===== Statistics for " + sample_token + " (predictions) ====="
            points_label = load_bin_file(lidarseg_preds_bin_path, type=gt_from)
        else:
            assert len(semantic_table) > 0, (
                "Error: There are no ground truth labels found for nuScenes-{} for {}.Are you loading the test set? "
                "\nIf you want to see the sample statistics for your predictions, pass a path to the appropriate "
                ".bin/npz file using the lidarseg_preds_bin_path argument.".format(gt_from, nusc.version))
            header = "===== Statistics for " + sample_token + " ====="
            points_label = None
        print(header)
        if points_label is None:
            points_label = labels.frame_labels(nusc, gt_from, [ref_sd_token])[0]
        indices = labels.class_counts(points_label, gt_from)
        lidarseg_counts = [0] * len(nusc.lidarseg_idx2name_mapping)  # the devkit's get_stats
        for class_idx in np.nonzero(indices)[0]:
            lidarseg_counts[class_idx] += indices[class_idx]
        counts = {nusc.lidarseg_idx2name_mapping[i]: lidarseg_counts[i] for i in range(len(lidarseg_counts))}
        for class_name, count in _sorted_counts(counts, sort_by):
            if count > 0:
                idx = nusc.lidarseg_name2idx_mapping[class_name]
                print("{:3}  {:40} n={:12,}".format(idx, class_name, count))
        print("=" * len(header))

    # --- the data call ----------------------------------------------------------------------------------------

    def map_pointcloud_to_image(self, pointsensor_token: str, camera_token: str, min_dist: float = 1.0,
                                render_intensity: bool = False, show_lidarseg: bool = False,
                                filter_lidarseg_labels=None, lidarseg_preds_bin_path: str = None,
                                show_panoptic: bool = False):
        """A lidar or radar frame's points in a camera image, as the devkit computes them (float32 steps):
        (points (3, n) pixels, coloring (n,) depth or intensity, the image as a PIL Image). Points nearer than
        `min_dist` to the camera plane or within 1 pixel of the border are left out. The labels colourings
        (`show_lidarseg`, `show_panoptic`) are not served: `nuparquet render --lidar --lidar-color lidarseg`."""
        from PIL import Image

        nusc = self.nusc
        if show_lidarseg or show_panoptic:
            raise NotServed("map_pointcloud_to_image(show_lidarseg/show_panoptic) is not served: "
                            "`nuparquet render OUT --scene NAME --lidar --lidar-color lidarseg|panoptic` draws the "
                            "labelled points; nusc._dataset.points(token, columns=['x', 'y', 'z', 'lidarseg_label']) "
                            "gives them")
        cam = nusc.get("sample_data", camera_token)
        pointsensor = nusc.get("sample_data", pointsensor_token)
        cls = LidarPointCloud if pointsensor["sensor_modality"] == "lidar" else RadarPointCloud
        pc = nusc._point_cloud(pointsensor, cls)
        im = Image.open(osp.join(nusc.dataroot, cam["filename"]))

        cs_record = nusc.get("calibrated_sensor", pointsensor["calibrated_sensor_token"])
        pc.rotate(Quaternion(cs_record["rotation"]).rotation_matrix)
        pc.translate(np.array(cs_record["translation"]))
        poserecord = nusc.get("ego_pose", pointsensor["ego_pose_token"])
        pc.rotate(Quaternion(poserecord["rotation"]).rotation_matrix)
        pc.translate(np.array(poserecord["translation"]))
        poserecord = nusc.get("ego_pose", cam["ego_pose_token"])
        pc.translate(-np.array(poserecord["translation"]))
        pc.rotate(Quaternion(poserecord["rotation"]).rotation_matrix.T)
        cs_record = nusc.get("calibrated_sensor", cam["calibrated_sensor_token"])
        pc.translate(-np.array(cs_record["translation"]))
        pc.rotate(Quaternion(cs_record["rotation"]).rotation_matrix.T)

        depths = pc.points[2, :]
        if render_intensity:
            assert pointsensor["sensor_modality"] == "lidar", \
                "Error: Can only render intensity for lidar, not %s!" % pointsensor["sensor_modality"]
            intensities = pc.points[3, :]
            intensities = (intensities - np.min(intensities)) / (np.max(intensities) - np.min(intensities))
            intensities = intensities ** 0.1
            coloring = np.maximum(0, intensities - 0.5)
        else:
            coloring = depths
        points = view_points(pc.points[:3, :], np.array(cs_record["camera_intrinsic"]), normalize=True)
        mask = np.ones(depths.shape[0], dtype=bool)
        mask = np.logical_and(mask, depths > min_dist)
        mask = np.logical_and(mask, points[0, :] > 1)
        mask = np.logical_and(mask, points[0, :] < im.size[0] - 1)
        mask = np.logical_and(mask, points[1, :] > 1)
        mask = np.logical_and(mask, points[1, :] < im.size[1] - 1)
        return points[:, mask], coloring[mask], im


def _needs_labels(nusc, gt_from: str) -> None:
    if not hasattr(nusc, gt_from):
        raise NotServed(f"Error: nuScenes-{gt_from} not installed! ({nusc.parquet} was converted without "
                        f"{gt_from}.json: convert a dataroot whose {nusc.version}/ holds it)")


def _sorted_counts(counts: dict, sort_by: str):
    if sort_by == "count":
        return sorted(counts.items(), key=lambda item: item[1])
    if sort_by == "name":
        return sorted(counts.items())
    return counts.items()


def _numpy_column(column) -> np.ndarray:
    return fixed_block(column)
