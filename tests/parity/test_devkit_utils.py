"""nuparquet.devkit.utils against nuscenes-devkit's nuscenes.utils: Box, the point clouds (files, sweeps aggregated
with from_file_multisweep, the radar filters), geometry_utils, splits, color_map, data_io, and the explorer's
map_pointcloud_to_image, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from pyquaternion import Quaternion

from devkit_pairs import box_values, open_pair
from devkit_same import assert_same
from conftest import SYNTH_VERSION
from nuparquet.devkit import NuScenes
from nuparquet.devkit.utils import color_map, data_classes, data_io, geometry_utils, splits


@pytest.fixture(scope="module")
def dk_utils():
    from nuscenes.utils import color_map as c, data_classes as d, data_io as io, geometry_utils as g, splits as s

    return {"data_classes": d, "geometry_utils": g, "splits": s, "color_map": c, "data_io": io}


def random_boxes(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        q = rng.normal(size=4) * rng.choice([1.0, 1.3])  # not always unit: pyquaternion normalises some paths
        yield (rng.uniform(-30, 30, 3).tolist(), rng.uniform(0.3, 8, 3).tolist(), q.tolist(),
               rng.integers(0, 5), float(rng.uniform()), rng.normal(size=3).tolist())


def test_box_methods_give_the_devkits_numbers(dk_utils):
    D = dk_utils["data_classes"]
    rng = np.random.default_rng(1)
    for center, size, q, label, score, velocity in random_boxes(200):
        ours = data_classes.Box(center, size, Quaternion(q), label=label, score=score, velocity=velocity, name="n",
                                token="t")
        theirs = D.Box(center, size, Quaternion(q), label=label, score=score, velocity=velocity, name="n", token="t")
        assert_same(box_values(ours), box_values(theirs))
        assert repr(ours) == repr(theirs) and ours == theirs and theirs == ours
        for factor in (1.0, 1.7):
            assert_same(ours.corners(factor), theirs.corners(factor))
        assert_same(ours.bottom_corners(), theirs.bottom_corners())
        assert_same(ours.rotation_matrix, theirs.rotation_matrix)
        move, turn = rng.normal(size=3) * 100, Quaternion(rng.normal(size=4))
        for box in (ours, theirs):
            box.translate(move)
            box.rotate(turn)
        assert_same(box_values(ours), box_values(theirs))
        copy = ours.copy()
        assert copy == ours and copy is not ours and copy.orientation is not ours.orientation
    default = data_classes.Box([1, 2, 3], [1, 2, 3], Quaternion())
    assert_same(box_values(default), box_values(D.Box([1, 2, 3], [1, 2, 3], Quaternion())))
    with pytest.raises(AssertionError):
        data_classes.Box([np.nan, 0, 0], [1, 1, 1], Quaternion())
    with pytest.raises(AssertionError):
        data_classes.Box([0, 0, 0], [1, 1, 1], [1, 0, 0, 0])


def test_boxes_draw_what_the_devkits_draw(dk_utils):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    D = dk_utils["data_classes"]
    view = np.array([[1266.0, 0, 816.5], [0, 1266.0, 491.5], [0, 0, 1]])
    for center, size, q, *_ in random_boxes(5, seed=4):
        center = [center[0] / 10, center[1] / 10, abs(center[2]) + 20]  # in front of the camera, in the image
        lines, images = [], []
        for cls in (data_classes.Box, D.Box):
            box = cls(center, size, Quaternion(q))
            fig, ax = plt.subplots()
            box.render(ax, view=view, normalize=True, colors=("g", "r", "b"))
            lines.append([(line.get_xydata().tolist(), line.get_color()) for line in ax.get_lines()])
            plt.close(fig)
            image = np.zeros((900, 1600, 3), dtype=np.uint8)
            box.render_cv2(image, view=view, normalize=True)
            images.append(image)
        assert lines[0] == lines[1] and len(lines[0]) == 13
        assert_same(images[0], images[1])
        assert images[0].any()


@pytest.mark.parametrize("shape", [(4, 5), (5, 4), (3, 5)])
def test_view_points_refuses_a_view_larger_than_4x4_as_the_devkit_asserts(dk_utils, shape):
    """A view matrix of more than 4 rows or columns: both raise the devkit's AssertionError (no padding error)."""
    points = np.ones((3, 2))
    with pytest.raises(AssertionError):
        dk_utils["geometry_utils"].view_points(points, np.ones(shape), False)
    with pytest.raises(AssertionError):
        geometry_utils.view_points(points, np.ones(shape), False)


def test_geometry_utils_give_the_devkits_numbers(dk_utils):
    G = dk_utils["geometry_utils"]
    rng = np.random.default_rng(2)
    points = rng.uniform(-20, 20, (3, 300))
    for view in (rng.normal(size=(3, 3)), rng.normal(size=(3, 4)), rng.normal(size=(4, 4)), np.eye(2)):
        for normalize in (True, False):
            if view.shape == (2, 2) and normalize:
                continue
            with np.errstate(all="ignore"):
                assert_same(geometry_utils.view_points(points, view, normalize), G.view_points(points, view, normalize))
    for translation, q in ((rng.normal(size=3) * 100, Quaternion(rng.normal(size=4))), ([1, 2, 3], Quaternion())):
        for inverse in (True, False):
            assert_same(geometry_utils.transform_matrix(translation, q, inverse),
                        G.transform_matrix(translation, q, inverse))
    assert_same(geometry_utils.transform_matrix(), G.transform_matrix())
    intrinsic = np.array([[1266.0, 0, 816.5], [0, 1266.0, 491.5], [0, 0, 1]])
    decided, grown = set(), 0
    for center, size, q, *_ in random_boxes(300, seed=5):
        center[2] = center[2] / 2 + 8
        box = data_classes.Box(center, size, Quaternion(q))
        theirs_box = dk_utils["data_classes"].Box(center, size, Quaternion(q))
        for level in (G.BoxVisibility.ALL, G.BoxVisibility.ANY, G.BoxVisibility.NONE):
            with np.errstate(all="ignore"):
                got = geometry_utils.box_in_image(box, intrinsic, (1600, 900), level)
                assert got == G.box_in_image(theirs_box, intrinsic, (1600, 900), level)
            decided.add((int(level), got))
        for factor in (1.0, 0.5):
            inside = geometry_utils.points_in_box(box, points, factor)
            assert_same(inside, G.points_in_box(theirs_box, points, factor))
        inside = geometry_utils.points_in_box(box, points)  # the default wlh_factor, the devkit's 1.0
        assert_same(inside, G.points_in_box(theirs_box, points))
        grown += int(G.points_in_box(theirs_box, points, 2.0).sum() > inside.sum())
    assert decided == {(0, True), (0, False), (1, True), (1, False), (2, True)}
    assert grown > 20  # boxes that a doubled box would give more points: the default factor is seen
    assert [int(v) for v in geometry_utils.BoxVisibility] == [int(v) for v in G.BoxVisibility]


def test_splits_color_map_and_label_files_are_the_devkits(dk_utils, extract_trainval_root, extract_trainval_out,
                                                          labelled_root, devkit):
    S = dk_utils["splits"]
    for name in ("train", "val", "test", "mini_train", "mini_val", "train_detect", "train_track"):
        assert getattr(splits, name) == getattr(S, name)
    assert splits.create_splits_scenes() == S.create_splits_scenes()
    assert splits.is_predefined_split("val") and not splits.is_predefined_split("mine")
    theirs = devkit.NuScenes("v1.0-trainval", dataroot=str(extract_trainval_root), verbose=False)
    ours = NuScenes("v1.0-trainval", dataroot=str(extract_trainval_root), parquet=extract_trainval_out, verbose=False)
    for nusc, module in ((ours, splits), (theirs, S)):  # the devkit needs every scene of the split: both fail alike
        with pytest.raises(KeyError, match="scene-0003"):
            module.create_splits_logs("val", nusc)
        with pytest.raises(AssertionError, match="not compatible"):
            module.create_splits_logs("mini_val", nusc)
    with pytest.raises(ValueError, match="splits.json"):
        splits.get_scenes_of_split("mine", ours)
    assert splits.get_scenes_of_split("val", ours) == S.get_scenes_of_split("val", theirs)
    assert list(color_map.get_colormap().items()) == list(dk_utils["color_map"].get_colormap().items())
    assert color_map.get_colormap() is not color_map.get_colormap()
    IO = dk_utils["data_io"]
    lidarseg = next((labelled_root / "lidarseg").rglob("*.bin"))
    panoptic = next((labelled_root / "panoptic").rglob("*.npz"))
    assert_same(data_io.load_bin_file(str(lidarseg)), IO.load_bin_file(str(lidarseg)))
    labels = data_io.load_bin_file(str(panoptic), type="panoptic")
    assert_same(labels, IO.load_bin_file(str(panoptic), type="panoptic"))
    assert_same(data_io.panoptic_to_lidarseg(labels), IO.panoptic_to_lidarseg(labels))
    with pytest.raises(TypeError):
        data_io.load_bin_file(str(lidarseg), type="other")


class _SceneLogs:
    """What create_splits_logs reads of a NuScenes (`version`, `scene`, `get("log", token)`): every one of the 1,000
    predefined scenes, each on one of 13 logs."""

    def __init__(self, version: str):
        self.version = version
        names = splits.train + splits.val + splits.test
        self.scene = [{"name": name, "log_token": f"log-{i % 13}"} for i, name in enumerate(names)]

    def get(self, table: str, token: str) -> dict:
        assert table == "log"
        return {"token": token, "logfile": f"logfile-of-{token}"}


def test_create_splits_logs_of_every_split_and_version_suffix_is_the_devkits(dk_utils):
    """Every predefined split against the three version suffixes, ours and the devkit's on the same input: the same
    logs where the split suits the version (sorted: both build them through a set), the same AssertionError where
    it does not."""
    S = dk_utils["splits"]
    suits = {"train": "trainval", "val": "trainval", "train_detect": "trainval", "train_track": "trainval",
             "mini_train": "mini", "mini_val": "mini", "test": "test"}
    for split, suffix in suits.items():
        for version in ("v1.0-trainval", "v1.0-mini", "v1.0-test"):
            nusc = _SceneLogs(version)
            if version.endswith(suffix):
                logs = sorted(splits.create_splits_logs(split, nusc))
                assert logs == sorted(S.create_splits_logs(split, nusc)) and logs, (split, version)
            else:
                messages = []
                for module in (splits, S):
                    with pytest.raises(AssertionError, match=f"split {split} which is not compatible with NuScenes "
                                                             f"version {version}") as raised:
                        module.create_splits_logs(split, nusc)
                    messages.append(str(raised.value))
                assert messages[0] == messages[1]  # word for word


def test_an_empty_label_file_fails_with_the_devkits_assertion_word_for_word(dk_utils, tmp_path):
    empty = tmp_path / "empty-labels.bin"
    empty.write_bytes(b"")
    with pytest.raises(AssertionError) as theirs:
        dk_utils["data_io"].load_bin_file(str(empty))
    with pytest.raises(AssertionError) as ours:
        data_io.load_bin_file(str(empty))
    assert str(ours.value) == str(theirs.value) == f"Error: {empty} is empty."


def test_point_cloud_files_and_their_methods_give_the_devkits_numbers(dk_utils, labelled_root, extract_root):
    D = dk_utils["data_classes"]
    lidar = str(next((labelled_root / "samples" / "LIDAR_TOP").glob("*.pcd.bin")))
    radars = [str(p) for p in sorted((extract_root / "samples").glob("RADAR_*/*.pcd"))[::20]]  # real radar states
    ours, theirs = data_classes.LidarPointCloud.from_file(lidar), D.LidarPointCloud.from_file(lidar)
    assert_same(ours.points, theirs.points)
    rng = np.random.default_rng(6)
    matrix, shift = rng.normal(size=(4, 4)), rng.normal(size=3)
    for cloud in (ours, theirs):
        cloud.remove_close(3.0)
        cloud.translate(shift)
        cloud.rotate(matrix[:3, :3])
        cloud.transform(matrix)
    assert_same(ours.points, theirs.points)
    assert ours.nbr_points() == theirs.nbr_points() < len(np.fromfile(lidar, dtype=np.float32)) // 5
    for cloud in (ours, theirs):
        np.random.seed(3)
        cloud.subsample(0.3)
    assert_same(ours.points, theirs.points)
    kept = {}
    try:
        for setting in ("default", "custom", "disabled"):
            if setting == "disabled":
                data_classes.RadarPointCloud.disable_filters()
                D.RadarPointCloud.disable_filters()
            kwargs = {"dynprop_states": [0, 2, 6], "ambig_states": range(5)} if setting == "custom" else {}
            kept[setting] = 0
            for path in radars:
                ours, theirs = (data_classes.RadarPointCloud.from_file(path, **kwargs),
                                D.RadarPointCloud.from_file(path, **kwargs))
                assert_same(ours.points, theirs.points)
                kept[setting] += ours.nbr_points()
    finally:
        data_classes.RadarPointCloud.default_filters()
        D.RadarPointCloud.default_filters()
    assert kept["default"] < kept["disabled"] and kept["custom"] != kept["default"], kept
    assert data_classes.RadarPointCloud.invalid_states == [0] == D.RadarPointCloud.invalid_states


@pytest.fixture(scope="module")
def labelled(request, devkit):
    return open_pair(request, devkit, "labelled")


def test_sweeps_aggregate_as_the_devkits_from_file_multisweep(labelled, dk_utils):
    D = dk_utils["data_classes"]
    several_lags = 0
    for sample in labelled.theirs.sample[1::2]:
        for channel, ours_cls, dk_cls in (("LIDAR_TOP", data_classes.LidarPointCloud, D.LidarPointCloud),
                                          ("RADAR_FRONT", data_classes.RadarPointCloud, D.RadarPointCloud),
                                          ("RADAR_BACK_LEFT", data_classes.RadarPointCloud, D.RadarPointCloud)):
            for nsweeps, min_distance in ((1, 1.0), (3, 1.0), (10, 2.5)):
                theirs = dk_cls.from_file_multisweep(labelled.theirs, sample, channel, "LIDAR_TOP", nsweeps,
                                                     min_distance)
                ours = ours_cls.from_file_multisweep(labelled.ours, labelled.ours.get("sample", sample["token"]),
                                                     channel, "LIDAR_TOP", nsweeps, min_distance)
                assert_same([ours[0].points, ours[1]], [theirs[0].points, theirs[1]], f"{channel} {nsweeps}")
                lags = np.unique(theirs[1]).size
                assert lags == 1 if nsweeps == 1 else lags >= 1
                several_lags += lags > 1
        # the devkit's classes accept nuparquet's NuScenes too (files under its dataroot)
        theirs = D.LidarPointCloud.from_file_multisweep(labelled.ours, sample, "LIDAR_TOP", "LIDAR_TOP", 3)
        ours = data_classes.LidarPointCloud.from_file_multisweep(labelled.theirs, sample, "LIDAR_TOP", "LIDAR_TOP", 3)
        assert_same(ours[0].points, theirs[0].points)
    assert several_lags >= 4  # sweeps were aggregated, not only keyframes


def test_keyframe_points_come_from_the_parquet_when_the_files_are_absent(labelled, tmp_path, dk_utils):
    D = dk_utils["data_classes"]
    ours = NuScenes(SYNTH_VERSION, dataroot=str(tmp_path), parquet=labelled.out, verbose=False)  # no sensor files
    for sample in labelled.theirs.sample:
        for channel, ours_cls, dk_cls in (("LIDAR_TOP", data_classes.LidarPointCloud, D.LidarPointCloud),
                                          ("RADAR_FRONT", data_classes.RadarPointCloud, D.RadarPointCloud)):
            theirs = dk_cls.from_file_multisweep(labelled.theirs, sample, channel, "LIDAR_TOP", 1)
            got = ours_cls.from_file_multisweep(ours, ours.get("sample", sample["token"]), channel, "LIDAR_TOP", 1)
            assert_same(got[0].points, theirs[0].points)
    sample = ours.get("sample", labelled.theirs.sample[-1]["token"])
    with pytest.raises(FileNotFoundError, match="--sensors lidar --sweeps"):
        data_classes.LidarPointCloud.from_file_multisweep(ours, sample, "LIDAR_TOP", "LIDAR_TOP", 2)


def test_map_pointcloud_to_image_gives_the_devkits_points(request, devkit):
    from nuscenes.nuscenes import NuScenesExplorer

    pair = open_pair(request, devkit, "synth")
    explorer = NuScenesExplorer(pair.theirs)
    seen = 0
    for sample in pair.theirs.sample[::3]:
        for camera in ("CAM_FRONT", "CAM_BACK_LEFT"):
            for sensor, intensity in (("LIDAR_TOP", False), ("LIDAR_TOP", True), ("RADAR_FRONT", False)):
                args = (sample["data"][sensor], sample["data"][camera])
                theirs = explorer.map_pointcloud_to_image(*args, render_intensity=intensity, min_dist=1.5)
                ours = pair.ours.explorer.map_pointcloud_to_image(*args, render_intensity=intensity, min_dist=1.5)
                assert_same([ours[0], ours[1], ours[2].size], [theirs[0], theirs[1], theirs[2].size])
                seen += ours[0].shape[1]
    assert seen > 1000


def test_point_clouds_render_their_height_and_intensity_as_the_devkits(dk_utils):
    """`PointCloud.render_height` / `render_intensity` scatter the points through `view`, coloured by z (row 2) and
    by intensity (row 3), with the devkit's limits: the same offsets, colour values and axis limits as the devkit's
    on the same (4, N) lidar points (intensity unlike z, so the two colourings differ)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    D = dk_utils["data_classes"]
    rng = np.random.default_rng(8)
    points = np.vstack([rng.uniform(-25, 25, (2, 40)), rng.uniform(-2, 3, (1, 40)),
                        rng.uniform(0, 255, (1, 40))]).astype(np.float32)
    view = np.array([[0.5, 0.2, 0, 1], [-0.2, 0.5, 0, -2], [0, 0, 1, 0], [0, 0, 0, 1]])
    drawn = {}
    for cls in (data_classes.LidarPointCloud, D.LidarPointCloud):
        for method, kwargs in (("render_height", {}), ("render_intensity", {}),
                               ("render_intensity", {"view": view, "x_lim": (-5, 8), "y_lim": (-9, 4),
                                                     "marker_size": 3})):
            fig, ax = plt.subplots()
            getattr(cls(points.copy()), method)(ax, **kwargs)
            (scatter,) = ax.collections
            drawn.setdefault(cls, []).append((scatter.get_offsets().tolist(), np.asarray(scatter.get_array()).tolist(),
                                              scatter.get_sizes().tolist(), ax.get_xlim(), ax.get_ylim()))
            plt.close(fig)
    ours, theirs = drawn[data_classes.LidarPointCloud], drawn[D.LidarPointCloud]
    assert ours == theirs
    assert ours[0][1] == points[2].tolist() and ours[1][1] == points[3].tolist()
