"""`render --lidar-color`: points read from lidar_points/ and coloured by lidarseg class land where the devkit's
`map_pointcloud_to_image(show_lidarseg=True)` puts them, in its colours; the file fallback gives the same points."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from conftest import SYNTH_VERSION
from nuparquet.cli.main import main

LIDAR_TOLERANCE_PX_M = 0.5  # as tests/parity/test_box_projection.py: pixel error x depth, the devkit rounds to float32


@pytest.fixture(scope="module")
def labelled_images(tmp_path_factory):
    from nuparquet.conversion import convert
    from nuparquet.synth import synthesize

    root = synthesize(tmp_path_factory.mktemp("colors") / "data", scenes=1, samples_per_scene=3, with_images=True,
                      with_lidar=True, seed=4, version=SYNTH_VERSION, with_can_bus=False)
    out = tmp_path_factory.mktemp("colors-out") / "out"
    convert(root, SYNTH_VERSION, out, sensors=("lidar",), workers=1)
    return root, out


def _lidar_points(out, root, color: str, *, from_dataset: bool = True):
    import nuparquet
    from nuparquet.frames.poses import cameras_from_frames
    from nuparquet.rendering.points import LidarPoints

    from nuparquet.dataset import Dataset

    ds = nuparquet.open(out)
    frames = ds.scan("frames").filter(pl.col("is_key_frame")).collect()
    cameras = frames.filter(pl.col("channel") == "CAM_FRONT")
    lidar = frames.filter(pl.col("channel") == "LIDAR_TOP")
    if not from_dataset:  # the same output as if converted without points: the sensor reader reads the files
        ds = Dataset(ds.root, dict(ds.manifest, datasets={k: v for k, v in ds.manifest["datasets"].items()
                                                          if k != "lidar_points"}))
    points = LidarPoints.build(cameras_from_frames(cameras), cameras, lidar, root, dataset=ds, color=color)
    return points, cameras, lidar


def test_lidarseg_colours_and_pixels_equal_devkit_map_pointcloud_to_image(labelled_images):
    from nuscenes.nuscenes import NuScenes
    from nuscenes.utils.color_map import get_colormap

    root, out = labelled_images
    nusc = NuScenes(SYNTH_VERSION, str(root), verbose=False)
    points, cameras, lidar = _lidar_points(out, root, "lidarseg")
    compared = 0
    for row, camera in enumerate(cameras.iter_rows(named=True)):
        loaded, missing = points.load(row)
        assert missing is None
        uv, depth_m, colours_bgr = loaded
        lidar_token = lidar.filter(pl.col("sample_token") == camera["sample_token"])["token"].item()
        kept, coloring, _ = nusc.explorer.map_pointcloud_to_image(lidar_token, camera["token"], show_lidarseg=True)
        assert uv.shape[0] == kept.shape[1] > 0  # the same points kept
        assert (np.abs(uv - kept[:2].T).max(axis=1) * depth_m).max() < LIDAR_TOLERANCE_PX_M
        expected_rgb = np.rint(coloring[:, :3] * 255).astype(np.uint8)  # the devkit colours by its colormap / 255
        assert np.array_equal(colours_bgr[:, ::-1], expected_rgb)
        assert len(np.unique(expected_rgb, axis=0)) > 1  # ground and at least one object class
        compared += uv.shape[0]
    assert compared > 100 and get_colormap()["flat.driveable_surface"] == (0, 207, 191)


def test_points_from_lidar_points_equal_points_from_the_files(labelled_images):
    root, out = labelled_images
    from_dataset, cameras, _ = _lidar_points(out, root, "depth")
    from_files, _, _ = _lidar_points(out, root, "depth", from_dataset=False)
    assert from_dataset.reader.sensors.converted_columns("lidar") and not from_files.reader.sensors.converted_columns(
        "lidar")
    for row in range(cameras.height):
        (uv_a, depth_a, _), _ = from_dataset.load(row)
        (uv_b, depth_b, _), _ = from_files.load(row)
        assert np.array_equal(uv_a, uv_b) and np.array_equal(depth_a, depth_b)


@pytest.mark.parametrize("color", ["lidarseg", "panoptic", "intensity"])
def test_render_lidar_color_draws_points_in_more_than_one_colour(labelled_images, tmp_path, color):
    import cv2

    _, out = labelled_images
    common = ["render", str(out), "--scene", "scene-0001", "--frame-format", "png", "--quiet"]
    assert main([*common, "--frames-dir", str(tmp_path / "plain")]) == 0
    assert main([*common, "--frames-dir", str(tmp_path / color), "--lidar-color", color]) == 0  # implies --lidar
    plain = cv2.imread(str(tmp_path / "plain" / "00001.png"))
    drawn = cv2.imread(str(tmp_path / color / "00001.png"))
    changed = drawn[(plain != drawn).any(axis=2)]
    assert len(changed) > 50 and len(np.unique(changed, axis=0)) > 1


def test_label_colours_need_converted_labels(labelled_images, tmp_path, capsys):
    root, _ = labelled_images
    from nuparquet.conversion import convert

    out = tmp_path / "no-points"
    convert(root, SYNTH_VERSION, out)
    code = main(["render", str(out), "--scene", "scene-0001", "--frames-dir", str(tmp_path / "f"),
                 "--lidar-color", "lidarseg", "--quiet"])
    assert code == 2 and "--sensors lidar" in capsys.readouterr().err


def test_bev_points_take_their_lidarseg_class_colour(labelled_images, tmp_path):
    """`--channel bev --lidar-color lidarseg`: each LIDAR_TOP keyframe point, moved to the global frame with the
    devkit's poses (pyquaternion), lies at the north-up view pixel of its x, y and shows the devkit colormap's
    colour of its lidarseg class (read with numpy from the label file)."""
    import cv2
    from nuscenes.nuscenes import NuScenes
    from nuscenes.utils.color_map import get_colormap
    from nuscenes.utils.data_classes import LidarPointCloud
    from pyquaternion import Quaternion

    root, out = labelled_images
    assert main(["render", str(out), "--scene", "scene-0001", "--channel", "bev", "--bev-up", "north",
                 "--lidar-color", "lidarseg", "--frames-dir", str(tmp_path / "frames"), "--frame-format", "png",
                 "--quiet"]) == 0
    nusc = NuScenes(SYNTH_VERSION, str(root), verbose=False)
    colormap, names = get_colormap(), {c["index"]: c["name"] for c in nusc.category if "index" in c}
    scene = nusc.get("scene", nusc.field2token("scene", "name", "scene-0001")[0])
    sample_token, k, checked, equal = scene["first_sample_token"], 0, 0, 0
    while sample_token:
        sample = nusc.get("sample", sample_token)
        lidar = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
        cloud = LidarPointCloud.from_file(str(root / lidar["filename"]))
        labels = np.fromfile(root / nusc.get("lidarseg", lidar["token"])["filename"], dtype=np.uint8)
        calibration = nusc.get("calibrated_sensor", lidar["calibrated_sensor_token"])
        pose = nusc.get("ego_pose", lidar["ego_pose_token"])
        cloud.rotate(Quaternion(calibration["rotation"]).rotation_matrix)
        cloud.translate(np.array(calibration["translation"]))
        cloud.rotate(Quaternion(pose["rotation"]).rotation_matrix)
        cloud.translate(np.array(pose["translation"]))
        image = cv2.imread(str(tmp_path / "frames" / f"{k:05d}.png"))
        h, w = image.shape[:2]
        s = h / 100.0  # default range +-50 m
        u = np.round((w - 1) / 2 + (cloud.points[0] - pose["translation"][0]) * s).astype(int)
        v = np.round((h - 1) / 2 - (cloud.points[1] - pose["translation"][1]) * s).astype(int)
        inside = (u >= 0) & (u < w) & (v >= 0) & (v < h) & ~((u < 0.3 * w) & (v < 0.35 * h))  # not the legend
        pixel = v[inside] * w + u[inside]
        # pixels that points of one class only fall on (a later point of another class would paint over)
        unique_pixels, first = np.unique(pixel, return_index=True)
        classes = {p: set() for p in unique_pixels.tolist()}
        for p, label in zip(pixel.tolist(), labels[inside].tolist()):
            classes[p].add(label)
        for p, label_set in classes.items():
            if len(label_set) != 1:
                continue
            expected = tuple(int(c) for c in colormap[names[label_set.pop()]][::-1])  # RGB -> BGR
            checked += 1
            equal += tuple(int(c) for c in image[p // w, p % w]) == expected
        k, sample_token = k + 1, sample["next"]
    assert checked > 500
    assert equal / checked > 0.9, (equal, checked)  # the rest: under boxes and the ego, drawn on top
    # the legend says how the points are coloured: a line of white text (nothing else in the view is pure white
    # but the ego, at the centre) in the top-left corner below the map layers' swatches (the last, the lane
    # divider's, a filled (215, 215, 215) block)
    image = cv2.imread(str(tmp_path / "frames" / "00000.png"))
    corner = image[:int(0.35 * image.shape[0]), :int(0.3 * image.shape[1])]
    swatch = np.flatnonzero((corner[:, 10:18] == 215).all(axis=(1, 2)))
    start = 0
    if len(swatch):
        start = swatch[np.r_[np.flatnonzero(np.diff(swatch) > 1), len(swatch) - 1][0]] + 1  # the first block's end
    assert (corner[start:] == 255).all(axis=2).sum() > 10


def test_panoptic_colours_are_the_devkits_table_per_instance_label():
    """Thing instances of one class get their own colours (the devkit's `generate_panoptic_colors` table indexed by
    the whole label), stuff its class colour, 0 the noise colour."""
    from nuscenes.panoptic.panoptic_utils import generate_panoptic_colors
    from nuscenes.utils.color_map import get_colormap

    from nuparquet.rendering.point_colors import label_rgb

    name2idx = {name: index for index, name in enumerate(get_colormap())}  # the lidarseg classes, noise = 0
    names = {index: name for name, index in name2idx.items()}
    assert names[17] == "vehicle.car" and names[24] == "flat.driveable_surface"
    state = np.random.get_state()
    table = generate_panoptic_colors(get_colormap(), name2idx)
    np.random.set_state(state)
    labels = np.array([17001, 17002, 24000, 0, 17001])
    got = label_rgb(labels, "panoptic", names)
    expected = np.rint(table[[17001, 17002]] * 255.0).astype(np.uint8)
    assert got[:2].tolist() == expected.tolist() and got[0].tolist() != got[1].tolist()
    assert got[2].tolist() == list(get_colormap()["flat.driveable_surface"])
    assert got[3].tolist() == list(get_colormap()["noise"]) and got[4].tolist() == got[0].tolist()


def test_intensity_levels_are_the_devkits_and_floored_at_zero():
    """`map_pointcloud_to_image(render_intensity=True)`: min-max scaled, to the power 0.1, minus 0.5, floored at 0:
    an intensity below 0.5**10 of the span (~0.1 %) is level 0, not negative."""
    from nuparquet.rendering.point_colors import intensity_levels

    intensity = np.array([2.0, 2.0005, 3.0, 4.0])  # scaled: 0, 0.00025, 0.5, 1
    scaled = (intensity - 2.0) / 2.0
    expected = np.maximum(0.0, scaled ** 0.1 - 0.5)  # the devkit's lines, in order
    assert expected[1] == 0.0 and scaled[1] ** 0.1 - 0.5 < 0  # the floor is reached
    np.testing.assert_array_equal(intensity_levels(intensity), expected)
    assert intensity_levels(np.full(3, 7.0)).tolist() == [0.0, 0.0, 0.0]  # no span: every level 0


def test_scalar_colours_are_matplotlibs_viridis_and_a_constant_the_lowest_colour_of_every_point():
    """`scatter(c=values)` colours through viridis scaled from the smallest value to the largest; with no span
    (every value the same, or vmin == vmax) matplotlib's Normalize maps every point to 0: the lowest colour."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    from nuparquet.rendering.point_colors import scalar_rgb

    def matplotlib_rgb(values, vmin=None, vmax=None):
        scaled = Normalize(vmin, vmax, clip=True)(np.asarray(values, dtype=np.float64))
        return np.rint(colormaps["viridis"](np.ma.getdata(scaled))[:, :3] * 255.0)

    for values, limits in (([0.5, 3.0, -1.0, 2.0, 1.0], {}), ([0.5, 3.0, -1.0], {"vmin": 0.0, "vmax": 2.0}),
                           (np.full(5, 1.5), {}), ([1.0, 2.0, 3.0], {"vmin": 2.0, "vmax": 2.0})):
        got = scalar_rgb(values, **limits)
        expected = matplotlib_rgb(values, **limits)
        assert got.shape == (len(values), 3) and got.dtype == np.uint8, (values, limits)
        assert np.abs(got.astype(np.int64) - expected).max() <= 2, (values, limits)  # OpenCV's table vs matplotlib's
    assert len({tuple(c) for c in scalar_rgb(np.full(5, 1.5)).tolist()}) == 1
    assert len({tuple(c) for c in scalar_rgb([0.5, 3.0, -1.0, 2.0, 1.0]).tolist()}) == 5
