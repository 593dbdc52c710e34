"""Real clients of the devkit's NuScenes, run unchanged on nuparquet.devkit.NuScenes: mmdetection3d's info converter
loop, the devkit's detection evaluation, PredictHelper and NuScenesExplorer.render_sample_data give what they give
with the devkit's object."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pyquaternion import Quaternion

from devkit_pairs import open_pair
from devkit_same import assert_same, differences
from mmdet3d_converter import fill_trainval_infos
from conftest import SYNTH_VERSION
from nuparquet.devkit import NuScenes

REFERENCE_INFOS = "nuscenes_infos_val_v1.json"


@pytest.fixture(scope="module")
def extract(request, devkit):
    return open_pair(request, devkit, "extract")


def test_mmdetection3d_infos_are_the_devkits_and_the_reference(extract, extract_root):
    theirs = fill_trainval_infos(extract.theirs, set(), set())
    ours = fill_trainval_infos(extract.ours, set(), set())
    assert_same(ours, theirs, "infos")
    lean = NuScenes(extract.version, dataroot=str(extract.root), parquet=extract.out, verbose=False,
                    keep_records=False)
    assert_same(fill_trainval_infos(lean, set(), set()), theirs, "infos without kept records")
    assert len(ours[1]) == 81 and sum(len(i["sweeps"]) for i in ours[1]) > 700
    # and they are what mmdetection3d v1.4.0 itself wrote for this extract (its machine's BLAS: to 1e-12)
    reference = json.loads((extract_root.parent / "nuscenes-extract-mmdet3d" / REFERENCE_INFOS).read_text())["infos"]
    found = []
    _close(_plain(ours[1], str(extract_root)), reference, "infos", found)
    assert not found, found[:5]


def test_mmdetection3d_infos_are_the_devkits_on_the_synthetic_sets(request, devkit):
    for name in ("synth", "irregular", "irregular_empty"):
        pair = open_pair(request, devkit, name)
        train = {pair.theirs.scene[0]["token"]}
        test = name == "irregular_empty"  # a test version: the converter leaves the annotations out
        assert_same(fill_trainval_infos(pair.ours, train, set(), test=test),
                    fill_trainval_infos(pair.theirs, train, set(), test=test), name)


def _plain(value, dataroot: str):
    """Infos as their JSON dump holds them: lists for arrays, Python scalars, ./data/nuscenes paths."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist(), dataroot)
    if isinstance(value, dict):
        return {k: _plain(v, dataroot) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v, dataroot) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, str):
        return value.replace(dataroot, "./data/nuscenes")
    return value


def _close(ours, reference, path: str, found: list) -> None:
    if isinstance(reference, dict):
        if list(ours) != list(reference):
            found.append(f"{path}: keys {list(ours)} vs {list(reference)}")
            return
        for key in reference:
            _close(ours[key], reference[key], f"{path}.{key}", found)
    elif isinstance(reference, list):
        if len(ours) != len(reference):
            found.append(f"{path}: length {len(ours)} vs {len(reference)}")
            return
        for i, (a, b) in enumerate(zip(ours, reference)):
            _close(a, b, f"{path}[{i}]", found)
    elif isinstance(reference, float) and isinstance(ours, float):
        if not (np.isclose(ours, reference, rtol=1e-12, atol=1e-12) or (np.isnan(ours) and np.isnan(reference))):
            found.append(f"{path}: {ours!r} vs {reference!r}")
    elif ours != reference or type(ours) is not type(reference):
        found.append(f"{path}: {ours!r} vs {reference!r}")


def perturbed_results(nusc, seed: int = 0) -> dict:
    """Detections made from the ground truth: 90% of the boxes, moved, resized, turned, scored at random."""
    from nuscenes.eval.detection.utils import category_to_detection_name

    rng = np.random.default_rng(seed)
    attributes = {a["token"]: a["name"] for a in nusc.attribute}
    default = {"car": "vehicle.parked", "truck": "vehicle.parked", "bus": "vehicle.moving", "trailer": "vehicle.parked",
               "construction_vehicle": "vehicle.parked", "pedestrian": "pedestrian.standing",
               "motorcycle": "cycle.without_rider", "bicycle": "cycle.without_rider", "traffic_cone": "", "barrier": ""}
    results = {}
    for sample in nusc.sample:
        boxes = []
        for token in sample["anns"]:
            record = nusc.get("sample_annotation", token)
            name = category_to_detection_name(record["category_name"])
            if name is None or rng.random() < 0.1:
                continue
            yaw = Quaternion(record["rotation"]).yaw_pitch_roll[0] + rng.normal(0, 0.2)
            velocity = nusc.box_velocity(token)[:2]
            boxes.append({
                "sample_token": sample["token"],
                "translation": (np.array(record["translation"]) + rng.normal(0, 0.5, 3)).tolist(),
                "size": (np.array(record["size"]) * rng.uniform(0.8, 1.2, 3)).tolist(),
                "rotation": Quaternion(axis=[0, 0, 1], radians=yaw).elements.tolist(),
                "velocity": [0.0, 0.0] if np.isnan(velocity).any() else (velocity + rng.normal(0, 0.5, 2)).tolist(),
                "detection_name": name, "detection_score": float(rng.uniform(0.05, 1)),
                "attribute_name": attributes[record["attribute_tokens"][0]] if record["attribute_tokens"]
                else default[name]})
        results[sample["token"]] = boxes
    return {"meta": {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False,
                     "use_external": False}, "results": results}


def test_detection_evaluation_gives_the_devkits_metrics(extract_trainval_root, extract_trainval_out, devkit,
                                                        tmp_path):
    from nuscenes.eval.common.loaders import add_center_dist, filter_eval_boxes, load_gt
    from nuscenes.eval.detection.config import config_factory
    from nuscenes.eval.detection.data_classes import DetectionBox
    from nuscenes.eval.detection.evaluate import DetectionEval

    theirs = devkit.NuScenes("v1.0-trainval", dataroot=str(extract_trainval_root), verbose=False)
    ours = NuScenes("v1.0-trainval", dataroot=str(extract_trainval_root), parquet=extract_trainval_out, verbose=False)
    path = tmp_path / "results.json"
    path.write_text(json.dumps(perturbed_results(theirs)))
    config = config_factory("detection_cvpr_2019")
    outcomes = []
    for nusc in (theirs, ours):
        evaluation = DetectionEval(nusc, config=config, result_path=str(path), eval_set="val",
                                   output_dir=str(tmp_path / type(nusc).__module__), verbose=False)
        metrics, metric_data = evaluation.evaluate()
        serialized = metrics.serialize()
        serialized.pop("eval_time")
        gt = load_gt(nusc, "val", DetectionBox)
        filtered = filter_eval_boxes(nusc, add_center_dist(nusc, gt), config.class_range)
        outcomes.append((serialized, metric_data.serialize(), evaluation.gt_boxes.serialize(),
                         evaluation.pred_boxes.serialize(), filtered.serialize()))
    for got, expected in zip(outcomes[1], outcomes[0]):
        assert not differences(got, expected), differences(got, expected)
    assert 0.2 < outcomes[1][0]["mean_ap"] < 0.95 and len(outcomes[1][2]) == 81


def test_predict_helper_answers_the_devkits_on_every_annotation_of_a_scene(extract):
    from nuscenes.prediction import PredictHelper

    helpers = PredictHelper(extract.theirs), PredictHelper(extract.ours)
    scene = extract.theirs.scene[1]
    samples, token = [], scene["first_sample_token"]
    while token:
        samples.append(extract.theirs.get("sample", token))
        token = samples[-1]["next"]
    calls = 0
    for sample in samples:
        for ann in sample["anns"]:
            instance = extract.theirs.get("sample_annotation", ann)["instance_token"]
            answers = []
            for helper in helpers:
                answer = []
                for in_agent_frame in (True, False):
                    answer.append(helper.get_future_for_agent(instance, sample["token"], 3, in_agent_frame))
                    answer.append(helper.get_past_for_agent(instance, sample["token"], 2, in_agent_frame))
                answer.append(helper.get_future_for_agent(instance, sample["token"], 2, True, just_xy=False))
                answer.append(helper.get_past_for_agent(instance, sample["token"], 2, False, just_xy=False))
                answer.append(helper.get_velocity_for_agent(instance, sample["token"]))
                answer.append(helper.get_acceleration_for_agent(instance, sample["token"]))
                answer.append(helper.get_heading_change_rate_for_agent(instance, sample["token"]))
                answer.append(helper.get_annotations_for_sample(sample["token"]))
                answers.append(answer)
            assert_same(answers[1], answers[0], f"{instance} {sample['token']}")
            calls += 1
    assert calls > 2000


@pytest.mark.parametrize("modality", ["camera", "lidar", "radar"])
def test_the_devkits_explorer_renders_sample_data_from_it_headlessly(synth_mapped_root, synth_out, devkit, tmp_path,
                                                                     modality):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from nuscenes.nuscenes import NuScenesExplorer
    from PIL import Image

    theirs = devkit.NuScenes(SYNTH_VERSION, dataroot=str(synth_mapped_root), verbose=False)
    ours = NuScenes(SYNTH_VERSION, dataroot=str(synth_mapped_root), parquet=synth_out, verbose=False)
    sample = theirs.sample[4]
    token = next(t for c, t in sample["data"].items() if c.startswith({"camera": "CAM", "lidar": "LIDAR",
                                                                          "radar": "RADAR"}[modality]))
    images = []
    for nusc in (theirs, ours):
        out = tmp_path / f"{type(nusc).__module__}.png"
        # underlay_map=False: the devkit's map underlay calls int() on 1-element arrays, which numpy 2 refuses (for
        # either object); the map masks themselves are compared in test_devkit_tables.py
        NuScenesExplorer(nusc).render_sample_data(token, nsweeps=3, out_path=str(out), verbose=False,
                                                  underlay_map=False)
        plt.close("all")
        images.append(np.asarray(Image.open(out)))
    assert_same(images[1], images[0])
    assert len(np.unique(images[0].reshape(-1, images[0].shape[-1]), axis=0)) > 20  # boxes and points drawn


def test_our_renderers_put_nuparquets_pictures_where_the_devkits_figures_go(extract, tmp_path):
    """`render_*` of our NuScenes draw with `nuparquet.rendering.pictures.single` (checked against the devkit's pixels in
    test_single_renders_devkit.py), take the devkit's arguments in its order, and write `out_path` / draw on `ax`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    import nuparquet
    from nuparquet.rendering.pictures import single

    ds, ours = nuparquet.open(extract.out), extract.ours
    sample = extract.theirs.sample[3]
    camera, lidar = sample["data"]["CAM_FRONT"], sample["data"]["LIDAR_TOP"]
    annotation = sample["anns"][0]
    instance = extract.theirs.get("sample_annotation", annotation)["instance_token"]

    def written(call, name):
        out = tmp_path / f"{name}.png"
        returned = call(str(out))
        assert np.array_equal(np.asarray(Image.open(out).convert("RGB")), returned)
        return returned

    expected = single.render_sample_data(ds, camera, box_vis_level="all")
    assert np.array_equal(written(lambda out: ours.render_sample_data(camera, True, 0, out_path=out, verbose=False),
                                  "camera"), expected)  # BoxVisibility.ALL as the number 0, positionally
    assert not np.array_equal(expected, single.render_sample_data(ds, camera, box_vis_level="none"))
    top = written(lambda out: ours.render_sample_data(lidar, axes_limit=20, out_path=out, verbose=False), "lidar")
    assert np.array_equal(top, single.render_sample_data(ds, lidar, axes_limit=20))  # (the extract has no sweeps)
    # NuScenes.render_pointcloud_in_image takes no `ax`: its fifth argument is out_path, as in the devkit
    back = written(lambda out: ours.render_pointcloud_in_image(sample["token"], 5, "LIDAR_TOP", "CAM_BACK", out),
                   "points")
    assert np.array_equal(back, single.render_pointcloud_in_image(ds, sample["token"], 5, "LIDAR_TOP", "CAM_BACK"))
    assert not np.array_equal(back, single.render_pointcloud_in_image(ds, sample["token"], camera_channel="CAM_FRONT"))
    assert np.array_equal(written(lambda out: ours.render_annotation(annotation, out_path=out), "annotation"),
                          single.render_annotation(ds, annotation))
    assert np.array_equal(written(lambda out: ours.render_instance(instance, out_path=out), "instance"),
                          single.render_instance(ds, instance))  # the annotation nearest the ego, as the devkit's
    figure, ax = plt.subplots()
    drawn = ours.explorer.render_sample_data(camera, ax=ax, verbose=False)
    assert np.array_equal(np.asarray(ax.images[0].get_array()), drawn)
    plt.close(figure)


def test_our_explorers_video_renderers_name_the_nuparquet_command_that_renders(extract):
    from nuparquet.devkit import NotServed

    token = extract.theirs.sample[0]["data"]["CAM_FRONT"]
    scene = extract.theirs.scene[0]["token"]
    for call in (lambda: extract.ours.render_scene(scene), lambda: extract.ours.render_scene_channel(scene),
                 lambda: extract.ours.render_scene_channel_lidarseg(scene, "CAM_FRONT"),
                 lambda: extract.ours.render_scene_lidarseg(scene),
                 lambda: extract.ours.explorer.render_ego_centric_map(token)):
        with pytest.raises(NotServed, match="nuparquet render"):
            call()
        with pytest.raises(NotImplementedError):
            call()
    with pytest.raises(NotServed, match="render_egoposes_on_map"):
        extract.ours.render_egoposes_on_map("boston-seaport")


def test_our_pointcloud_in_image_draws_the_lidarseg_predictions_it_is_given(lidarseg_root, lidarseg_out, tmp_path):
    """`render_pointcloud_in_image(..., show_lidarseg=True, lidarseg_preds_bin_path=...)` of our NuScenes and its
    explorer colour the points by the prediction file, as `nuparquet.rendering.pictures.single` does with the same file
    (checked against the devkit's pixels in test_single_renders_devkit.py); the predictions (every point labelled
    class 1) change the picture from the ground-truth one."""
    import nuparquet
    from nuparquet.rendering.pictures import single

    ours = NuScenes(SYNTH_VERSION, dataroot=str(lidarseg_root), parquet=lidarseg_out, verbose=False)
    ds = nuparquet.open(lidarseg_out, dataroot=lidarseg_root)
    sample = ours.sample[1]
    lidar = ours.get("sample_data", sample["data"]["LIDAR_TOP"])
    points = (lidarseg_root / lidar["filename"]).stat().st_size // (5 * 4)
    predictions = tmp_path / "predictions.bin"
    np.ones(points, np.uint8).tofile(predictions)
    expected = single.render_pointcloud_in_image(ds, sample["token"], point_color="lidarseg",
                                                 lidarseg_preds_bin_path=str(predictions))
    truth = single.render_pointcloud_in_image(ds, sample["token"], point_color="lidarseg")
    assert not np.array_equal(expected, truth)
    for render in (ours.render_pointcloud_in_image, ours.explorer.render_pointcloud_in_image):
        drawn = render(sample["token"], show_lidarseg=True, lidarseg_preds_bin_path=str(predictions), verbose=False)
        assert np.array_equal(drawn, expected)


def test_our_render_sample_draws_only_the_lidarseg_classes_it_is_asked_for(lidarseg_root, lidarseg_out):
    """`render_sample(token, show_lidarseg=True, filter_lidarseg_labels=[...])` of our NuScenes is
    `nuparquet.rendering.pictures.single.render_sample` with the same filter (checked against the devkit's pixels in
    test_single_renders_devkit.py); the filter changes the picture."""
    import nuparquet
    from nuparquet.rendering.pictures import single

    ours = NuScenes(SYNTH_VERSION, dataroot=str(lidarseg_root), parquet=lidarseg_out, verbose=False)
    ds = nuparquet.open(lidarseg_out, dataroot=lidarseg_root)
    sample = ours.sample[1]
    labels = np.fromfile(lidarseg_root / ours.get("lidarseg", sample["data"]["LIDAR_TOP"])["filename"], np.uint8)
    kept = int(np.bincount(labels).argmax())
    expected = single.render_sample(ds, sample["token"], point_color="lidarseg", filter_lidarseg_labels=[kept])
    assert not np.array_equal(expected, single.render_sample(ds, sample["token"], point_color="lidarseg"))
    drawn = ours.render_sample(sample["token"], show_lidarseg=True, filter_lidarseg_labels=[kept], verbose=False)
    assert np.array_equal(drawn, expected)


def test_the_renderers_not_served_name_the_devkit_call_that_draws_them(synth_root, synth_out):
    """Each video renderer names the `nuparquet render` command that renders it, and each unserved renderer says
    that the devkit's explorer, NuScenesExplorer(nusc).<the same method>(...), accepts our object."""
    from nuparquet.devkit import NotServed

    ours = NuScenes(SYNTH_VERSION, dataroot=str(synth_root), parquet=synth_out, verbose=False)
    scene = ours.scene[0]["token"]
    calls = {"render_scene": (scene,), "render_scene_channel": (scene,),
             "render_scene_channel_lidarseg": (scene, "CAM_FRONT"), "render_scene_lidarseg": (scene,),
             "render_ego_centric_map": (ours.sample[0]["data"]["CAM_FRONT"],),
             "render_egoposes_on_map": ("boston-seaport",)}
    for name, args in calls.items():
        for owner in (ours, ours.explorer):
            if not hasattr(owner, name):  # render_ego_centric_map is the explorer's only
                continue
            with pytest.raises(NotServed) as caught:
                getattr(owner, name)(*args)
            message = str(caught.value)
            assert f"nuscenes.nuscenes.NuScenesExplorer(nusc).{name}(...) also accepts this object" in message
            assert message.startswith(f"{name} ")
            assert ("nuparquet render OUT --scene NAME" in message) == (name != "render_egoposes_on_map")


def test_our_render_sample_data_takes_the_devkits_arguments_in_order_and_shows_by_default(synth_root, synth_out,
                                                                                          monkeypatch):
    """`render_sample_data` of our NuScenes and its explorer take the devkit's arguments positionally (token,
    with_anns, box_vis_level, ...), draw what `nuparquet.rendering.pictures.single` draws with them, and, as the devkit's
    `verbose=True` default does, show the figure when called with no out_path or ax (plt.show once per call)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import nuparquet
    from nuparquet.rendering.pictures import single

    ours = NuScenes(SYNTH_VERSION, dataroot=str(synth_root), parquet=synth_out, verbose=False)
    ds = nuparquet.open(synth_out, dataroot=synth_root)
    camera = ours.sample[1]["data"]["CAM_FRONT"]
    without = single.render_sample_data(ds, camera, with_anns=False)
    with_boxes = single.render_sample_data(ds, camera)
    assert not np.array_equal(without, with_boxes)  # the synthetic camera sees boxes: with_anns matters
    shown = []
    monkeypatch.setattr(plt, "show", lambda *args, **kwargs: shown.append(plt.gcf().number))
    try:
        for owner in (ours, ours.explorer):
            assert np.array_equal(owner.render_sample_data(camera, False, "any", verbose=False), without)
            assert not shown
            assert np.array_equal(owner.render_sample_data(camera), with_boxes)  # verbose=True: shown
            assert len(shown) == 1
            shown.clear()
    finally:
        plt.close("all")
