"""Pictures of one thing (`nuparquet.rendering.pictures.single`) against the devkit's geometry: the boxes the devkit's
`get_sample_data` gives (camera, flat ego frame), the points its `from_file_multisweep` / `map_pointcloud_to_image`
give, its radar velocity arrows, its choice of camera for an annotation and of annotation for an instance, its map
polygons, masks, centrelines and ego poses, each computed here with the devkit and found on the drawn pixels.

A drawing is checked by difference: the picture with the geometry against the same picture without it (or the raw
camera image, or the empty background) must change at the devkit's geometry, and (where it says so) nowhere else."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest

import nuparquet
from conftest import SYNTH_VERSION
from nuparquet.rendering.pictures import single
from nuparquet.rendering.palette import MAP_LAYER_RGB, category_rgb

os.environ.setdefault("MPLBACKEND", "Agg")
BACKGROUND = np.array([32, 32, 32])  # the views from above (bev.BACKGROUND_BGR), RGB alike
SIZE, LIMIT = 900, 40.0  # the top views' side (px) and axes_limit (m)


@pytest.fixture(scope="module")
def nusc(synth_root, devkit):
    return devkit.NuScenes(SYNTH_VERSION, str(synth_root), verbose=False)


@pytest.fixture(scope="module")
def ds(synth_out):
    return nuparquet.open(synth_out)


@pytest.fixture(scope="module")
def sample(nusc):
    """A sample in the middle of the first scene: sweeps before it, boxes around it."""
    scene = nusc.scene[0]
    token = scene["first_sample_token"]
    for _ in range(3):
        token = nusc.get("sample", token)["next"]
    return nusc.get("sample", token)


def _top_pixels(xy):
    s = SIZE / (2 * LIMIT)
    return np.c_[(xy[:, 0] + LIMIT) * s - 0.5, (LIMIT - xy[:, 1]) * s - 0.5]


def _inside(px, shape, margin=2):
    return (px[:, 0] >= margin) & (px[:, 0] < shape[1] - margin) & (px[:, 1] >= margin) & (px[:, 1] < shape[0] - margin)


def _edge_hits(changed: np.ndarray, boxes) -> tuple[int, int]:
    """(edge pixels checked, of which drawn): each box's top-view edge points away from the picture's border and
    corners, and whether the drawing changed a pixel within 1 px of each."""
    checked = hits = 0
    for corners, _ in boxes:
        px = _top_pixels(_edge_points(corners))
        keep = _inside(px, changed.shape, 3) & _away_from_corners(px, changed.shape)
        for u, v in np.rint(px[keep]).astype(int):
            hits += changed[v - 1:v + 2, u - 1:u + 2].any()
            checked += 1
    return checked, hits


def _away_from_corners(px, shape):
    """Pixels clear of the caption (bottom left) and the legend (top right)."""
    return ~((px[:, 0] < 200) & (px[:, 1] > shape[0] - 40)) & ~((px[:, 0] > shape[1] - 320) & (px[:, 1] < 300))


def _devkit_flat_view(nusc, sd_token, nsweeps):
    """The devkit's render_sample_data for a lidar / radar frame: its points in the flat ego frame, their
    velocities' arrows (radar) and the boxes' corners, step for step."""
    from nuscenes.utils.data_classes import LidarPointCloud, RadarPointCloud
    from nuscenes.utils.geometry_utils import transform_matrix, view_points
    from pyquaternion import Quaternion

    sd = nusc.get("sample_data", sd_token)
    sample = nusc.get("sample", sd["sample_token"])
    ref = nusc.get("sample_data", sample["data"]["LIDAR_TOP"])
    cls = LidarPointCloud if sd["sensor_modality"] == "lidar" else RadarPointCloud
    pc, _ = cls.from_file_multisweep(nusc, sample, sd["channel"], "LIDAR_TOP", nsweeps=nsweeps)
    cs = nusc.get("calibrated_sensor", ref["calibrated_sensor_token"])
    pose = nusc.get("ego_pose", ref["ego_pose_token"])
    ref_to_ego = transform_matrix(cs["translation"], Quaternion(cs["rotation"]))
    yaw = Quaternion(pose["rotation"]).yaw_pitch_roll[0]
    flat = np.eye(4)
    flat[:3, :3] = np.dot(Quaternion(scalar=np.cos(yaw / 2), vector=[0, 0, np.sin(yaw / 2)]).rotation_matrix,
                          Quaternion(pose["rotation"]).inverse.rotation_matrix)
    viewpoint = flat @ ref_to_ego
    points = view_points(pc.points[:3, :], viewpoint, normalize=False)
    arrows = None
    if cls is RadarPointCloud:
        radar_cs = nusc.get("calibrated_sensor", sd["calibrated_sensor_token"])
        velocities = np.vstack((pc.points[8:10, :], np.zeros(pc.points.shape[1])))
        velocities = Quaternion(radar_cs["rotation"]).rotation_matrix @ velocities
        velocities = Quaternion(cs["rotation"]).rotation_matrix.T @ velocities
        velocities[2, :] = 0
        deltas = np.clip(6 * (view_points(pc.points[:3, :] + velocities, viewpoint, normalize=False) - points), -20, 20)
        arrows = deltas[:2].T
    _, boxes, _ = nusc.get_sample_data(ref["token"], use_flat_vehicle_coordinates=True)
    return points[:2].T, arrows, [(b.corners()[:2].T, b.name) for b in boxes]


def _edge_points(corners_xy, n=9):
    """Points along the edges of boxes seen from above: the footprint (corners 0-1-5-4), t in 0.15..0.85."""
    outline = corners_xy[[0, 1, 5, 4, 0]]
    t = np.linspace(0.15, 0.85, n)[:, None]
    return np.concatenate([a + t * (b - a) for a, b in zip(outline[:-1], outline[1:])])


# --- sample_data: lidar and radar from above ----------------------------------------------------------------------


@pytest.mark.parametrize("channel, nsweeps", [("LIDAR_TOP", 1), ("LIDAR_TOP", 5), ("RADAR_FRONT", 5)])
def test_points_from_above_lie_where_the_devkit_puts_them(nusc, ds, sample, channel, nsweeps):
    token = sample["data"][channel]
    points, arrows, _ = _devkit_flat_view(nusc, token, nsweeps)
    picture = single.render_sample_data(ds, token, with_anns=False, nsweeps=nsweeps, underlay_map=False)
    assert picture.shape == (SIZE, SIZE, 3)
    px = _top_pixels(points)
    keep = _inside(px, picture.shape) & _away_from_corners(px, picture.shape)
    u, v = np.rint(px[keep]).astype(int).T
    drawn = (picture[v, u] != BACKGROUND).any(axis=1)
    assert keep.sum() > (20 if channel.startswith("RADAR") else 3000) and drawn.mean() > 0.99
    if arrows is None:  # lidar: nothing drawn away from the devkit's points
        near = np.zeros(picture.shape[:2], np.uint8)
        for (a, b) in np.rint(px[np.abs(px).max(axis=1) < 2 * SIZE]).astype(int):
            cv2.circle(near, (int(a), int(b)), 3, 1, -1)
        changed = (picture != BACKGROUND).any(axis=2)
        ego = np.zeros_like(near)
        cv2.circle(ego, (SIZE // 2, SIZE // 2), 20, 1, -1)  # the ego marker
        stray = changed & (near == 0) & (ego == 0)
        stray[SIZE - 40:, :200] = False  # the caption
        assert stray.sum() < 0.001 * changed.sum()
    else:  # radar: each arrow runs from its point along the devkit's 6x velocity
        moving = np.linalg.norm(arrows, axis=1) > 3.0
        assert moving.sum() > 3
        hits = total = 0
        for start, delta in zip(points[moving], arrows[moving]):
            for t in (0.4, 0.6, 0.8):
                u, v = np.rint(_top_pixels((start + t * delta)[None])[0]).astype(int)
                if 0 <= u < SIZE and 0 <= v < SIZE:
                    hits += bool((picture[v, u] != BACKGROUND).any())
                    total += 1
        assert total > 10 and hits / total > 0.9


def test_boxes_from_above_lie_on_the_devkit_flat_ego_boxes(nusc, ds, sample):
    token = sample["data"]["LIDAR_TOP"]
    _, _, boxes = _devkit_flat_view(nusc, token, 1)
    with_boxes = single.render_sample_data(ds, token, underlay_map=False)
    without = single.render_sample_data(ds, token, with_anns=False, underlay_map=False)
    changed = (with_boxes != without).any(axis=2)
    checked, hits = _edge_hits(changed, boxes)
    assert checked > 200 and hits / checked > 0.97
    # shifted by 2 m the same check fails: the boxes are where the devkit says, not just somewhere
    shifted = [(c + [2.0, 0.0], n) for c, n in boxes]
    miss = sum(changed[v, u] for c, _ in shifted for u, v in np.rint(_top_pixels(_edge_points(c, 3))).astype(int)
               if 3 <= u < SIZE - 3 and 3 <= v < SIZE - 3)
    assert miss < 0.5 * checked * 3 / 9


def test_boxes_from_above_in_the_sensor_frame_lie_on_the_devkits_sensor_boxes(nusc, ds, sample):
    """use_flat_vehicle_coordinates=False: the devkit draws the lidar in its own frame (viewpoint the identity) and
    the boxes `get_sample_data` gives in that frame."""
    token = sample["data"]["LIDAR_TOP"]
    _, sensor_boxes, _ = nusc.get_sample_data(token)  # the lidar's own frame
    boxes = [(b.corners()[:2].T, b.name) for b in sensor_boxes]
    flat_boxes = _devkit_flat_view(nusc, token, 1)[2]
    # the two frames differ here by more than the tolerance of the check (else the test would not tell them apart)
    assert max(np.abs(a - b).max() for (a, _), (b, _) in zip(boxes, flat_boxes)) > 1.0
    with_boxes = single.render_sample_data(ds, token, use_flat_vehicle_coordinates=False, underlay_map=False)
    without = single.render_sample_data(ds, token, with_anns=False, use_flat_vehicle_coordinates=False,
                                        underlay_map=False)
    changed = (with_boxes != without).any(axis=2)


    checked, hits = _edge_hits(changed, boxes)
    assert checked > 200 and hits / checked > 0.97
    checked, hits = _edge_hits(changed, flat_boxes)  # not the flat ego frame's boxes
    assert hits / checked < 0.5


def test_lidarseg_from_above_takes_the_class_colours_and_the_filter(nusc, ds, sample):
    from nuscenes.lidarseg.lidarseg_utils import paint_points_label

    token = sample["data"]["LIDAR_TOP"]
    picture = single.render_sample_data(ds, token, with_anns=False, underlay_map=False, point_color="lidarseg")
    _, _, _ = _devkit_flat_view(nusc, token, 1)
    labels_file = os.path.join(nusc.dataroot, nusc.get("lidarseg", token)["filename"])
    colours = np.rint(paint_points_label(labels_file, None, nusc.lidarseg_name2idx_mapping, nusc.colormap)[:, :3]
                      * 255).astype(int)
    # points alone in their 5x5 neighbourhood: their pixel shows their own class colour
    px, lonely = _keyframe_top_pixels(nusc, token, picture.shape)
    assert lonely.sum() > 200
    assert (picture[px[lonely, 1], px[lonely, 0]] == colours[lonely]).all(axis=1).mean() > 0.98
    # filter_lidarseg_labels keeps the classes asked for, hides the others
    labels = np.fromfile(labels_file, dtype=np.uint8)
    kept_class = int(np.bincount(labels).argmax())
    filtered = single.render_sample_data(ds, token, with_anns=False, underlay_map=False, point_color="lidarseg",
                                         filter_lidarseg_labels=[kept_class])
    hidden = lonely & (labels != kept_class)
    shown = lonely & (labels == kept_class)
    assert hidden.sum() > 20 and shown.sum() > 20
    assert (filtered[px[hidden, 1], px[hidden, 0]] == BACKGROUND).all(axis=1).mean() > 0.98
    assert (filtered[px[shown, 1], px[shown, 0]] == colours[shown]).all(axis=1).mean() > 0.98


def _keyframe_top_pixels(nusc, token, shape):
    """The devkit's lidar keyframe `token` as its labelled render_sample_data loads it (`LidarPointCloud.from_file`:
    every point, in the label file's order) in the flat view's pixels, and which of them lie alone in their 5x5
    neighbourhood, clear of the caption and the legend (their pixel can only show their own colour)."""
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import transform_matrix, view_points
    from pyquaternion import Quaternion

    ref = nusc.get("sample_data", token)
    pc = LidarPointCloud.from_file(os.path.join(nusc.dataroot, ref["filename"]))
    cs, pose = nusc.get("calibrated_sensor", ref["calibrated_sensor_token"]), nusc.get("ego_pose", ref["ego_pose_token"])
    yaw = Quaternion(pose["rotation"]).yaw_pitch_roll[0]
    flat = np.eye(4)
    flat[:3, :3] = Quaternion(scalar=np.cos(yaw / 2), vector=[0, 0, np.sin(yaw / 2)]).rotation_matrix @ \
        Quaternion(pose["rotation"]).inverse.rotation_matrix
    xy = view_points(pc.points[:3], flat @ transform_matrix(cs["translation"], Quaternion(cs["rotation"])), False)[:2].T
    px = np.rint(_top_pixels(xy)).astype(int)
    keep = _inside(px, shape, 3) & _away_from_corners(px, shape)
    occupancy = np.zeros(shape[:2], np.int32)
    np.add.at(occupancy, (px[keep, 1], px[keep, 0]), 1)
    lonely = keep.copy()
    lonely[keep] = cv2.boxFilter(occupancy.astype(np.float32), -1, (5, 5), normalize=False)[px[keep, 1], px[keep, 0]] == 1
    return px, lonely


def test_panoptic_from_above_takes_the_devkits_panoptic_colours(nusc, ds, sample):
    """show_panoptic: each point in the colour the devkit's `paint_panop_points_label` gives it (things by
    instance, stuff by class), from the frame's panoptic label file."""
    from nuscenes.panoptic.panoptic_utils import paint_panop_points_label

    token = sample["data"]["LIDAR_TOP"]
    picture = single.render_sample_data(ds, token, with_anns=False, underlay_map=False, point_color="panoptic")
    labels_file = os.path.join(nusc.dataroot, nusc.get("panoptic", token)["filename"])
    colours = np.rint(paint_panop_points_label(labels_file, None, nusc.lidarseg_name2idx_mapping, nusc.colormap)[:, :3]
                      * 255).astype(int)
    px, lonely = _keyframe_top_pixels(nusc, token, picture.shape)
    labels = np.load(labels_file)["data"]
    assert lonely.sum() > 200 and (labels[lonely] % 1000 > 0).sum() > 10  # things among the points checked
    assert (picture[px[lonely, 1], px[lonely, 0]] == colours[lonely]).all(axis=1).mean() > 0.98


# --- sample_data: a camera ----------------------------------------------------------------------------------------


def _camera_edges(nusc, token, box_vis_level):
    """The devkit's camera boxes (`get_sample_data` at `box_vis_level`): points along their 12 edges, by box."""
    from nuscenes.utils.geometry_utils import view_points

    _, boxes, intrinsic = nusc.get_sample_data(token, box_vis_level=box_vis_level)
    edges = {}
    for box in boxes:
        corners = view_points(box.corners(), intrinsic, normalize=True)[:2].T
        pairs = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
        t = np.linspace(0.2, 0.8, 7)[:, None]
        edges[box.token] = np.concatenate([corners[a] + t * (corners[b] - corners[a]) for a, b in pairs])
    return edges


@pytest.mark.parametrize("level", ["ANY", "ALL"])
def test_camera_boxes_are_the_devkits_at_each_visibility_level(nusc, ds, sample, level):
    from nuscenes.utils.geometry_utils import BoxVisibility

    token = sample["data"]["CAM_FRONT"]
    edges = _camera_edges(nusc, token, getattr(BoxVisibility, level))
    picture = single.render_sample_data(ds, token, box_vis_level=level.lower())
    plain = single.render_sample_data(ds, token, with_anns=False)
    changed = (picture != plain).any(axis=2)
    assert changed.any()
    hits = checked = 0
    for points in edges.values():
        px = np.rint(points).astype(int)
        keep = _inside(px, changed.shape, 3) & ~((px[:, 0] < 200) & (px[:, 1] > changed.shape[0] - 40))
        for u, v in px[keep]:
            hits += changed[v - 1:v + 2, u - 1:u + 2].any()
            checked += 1
    assert checked > 20 and hits / checked > 0.97
    # nothing drawn away from the devkit's boxes
    near = np.zeros(changed.shape, np.uint8)
    for points in edges.values():
        for (a, b), (c, d) in zip(np.rint(points[:-1]).astype(int), np.rint(points[1:]).astype(int)):
            cv2.line(near, (int(a), int(b)), (int(c), int(d)), 1, 9)
    from nuscenes.utils.geometry_utils import view_points

    _, boxes, intrinsic = nusc.get_sample_data(token, box_vis_level=getattr(BoxVisibility, level))
    for box in boxes:  # every edge of the devkit's boxes, whole (the sampled points cover 0.2..0.8 of each)
        corners = np.rint(view_points(box.corners(), intrinsic, True)[:2].T).astype(int)
        for a, b in [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7),
                     (0, 2), (1, 3)]:
            cv2.line(near, tuple(corners[a].tolist()), tuple(corners[b].tolist()), 1, 9)
    stray = changed & (near == 0)
    stray[-40:, :200] = False  # the caption
    assert stray.sum() < 0.002 * changed.sum()


# --- a sample's points on a camera image --------------------------------------------------------------------------


@pytest.mark.parametrize("channel", ["LIDAR_TOP", "RADAR_FRONT"])
def test_pointcloud_in_image_draws_the_devkits_points(nusc, ds, sample, synth_root, channel):
    points, coloring, _ = nusc.explorer.map_pointcloud_to_image(sample["data"][channel], sample["data"]["CAM_FRONT"])
    picture = single.render_pointcloud_in_image(ds, sample["token"], pointsensor_channel=channel)
    raw = cv2.imread(str(synth_root / nusc.get("sample_data", sample["data"]["CAM_FRONT"])["filename"]))[..., ::-1]
    changed = (picture.astype(int) - raw).__abs__().max(axis=2) > 12
    px = np.rint(points[:2].T).astype(int)
    keep = _inside(px, changed.shape, 2) & ~((px[:, 0] < 200) & (px[:, 1] > changed.shape[0] - 40))
    assert keep.sum() > (10 if channel.startswith("RADAR") else 300)
    assert np.mean([changed[v - 1:v + 2, u - 1:u + 2].any() for u, v in px[keep]]) > 0.97
    near = np.zeros(changed.shape, np.uint8)
    for u, v in px:
        cv2.circle(near, (int(u), int(v)), 5, 1, -1)
    stray = changed & (near == 0)
    stray[-40:, :220] = False
    assert stray.sum() < 0.01 * changed.sum()


def test_pointcloud_in_image_lidarseg_colours_and_filter(nusc, ds, sample):
    from nuscenes.lidarseg.lidarseg_utils import paint_points_label

    lidar, camera = sample["data"]["LIDAR_TOP"], sample["data"]["CAM_BACK"]
    labels_file = os.path.join(nusc.dataroot, nusc.get("lidarseg", lidar)["filename"])
    kept = int(np.bincount(np.fromfile(labels_file, np.uint8)).argmax())
    points, coloring, _ = nusc.explorer.map_pointcloud_to_image(lidar, camera, show_lidarseg=True,
                                                               filter_lidarseg_labels=[kept])
    picture = single.render_pointcloud_in_image(ds, sample["token"], camera_channel="CAM_BACK", point_color="lidarseg",
                                                filter_lidarseg_labels=[kept])
    px = np.rint(points[:2].T).astype(int)
    shown = coloring[:, 3] == 1  # the devkit hides the other classes (alpha 0)
    expected = np.rint(coloring[:, :3] * 255).astype(int)
    occupancy = np.zeros(picture.shape[:2], np.int32)
    np.add.at(occupancy, (px[:, 1], px[:, 0]), 1)
    lonely = cv2.boxFilter(occupancy.astype(np.float32), -1, (7, 7), normalize=False)[px[:, 1], px[:, 0]] == 1
    sel = shown & lonely & _away_from_corners(px, picture.shape)
    assert sel.sum() > 30 and (~shown).sum() > 30
    assert (picture[px[sel, 1], px[sel, 0]] == expected[sel]).all(axis=1).mean() > 0.98
    del paint_points_label


def test_sample_with_lidarseg_paints_each_camera_with_the_devkits_lidarseg_points(nusc, ds, sample, synth_root):
    """render_sample(show_lidarseg=True): the devkit draws every camera with `render_pointcloud_in_image` of the
    lidar's lidarseg points (filter_lidarseg_labels applied); the camera tile shows those points in their class
    colours, hides the filtered ones, and is the raw image elsewhere; the lidar's view from above likewise."""
    from nuscenes.lidarseg.lidarseg_utils import paint_points_label

    lidar, camera = sample["data"]["LIDAR_TOP"], sample["data"]["CAM_BACK"]
    labels_file = os.path.join(nusc.dataroot, nusc.get("lidarseg", lidar)["filename"])
    kept = int(np.bincount(np.fromfile(labels_file, np.uint8)).argmax())
    points, coloring, _ = nusc.explorer.map_pointcloud_to_image(lidar, camera, show_lidarseg=True,
                                                               filter_lidarseg_labels=[kept])
    picture = single.render_sample(ds, sample["token"], point_color="lidarseg", filter_lidarseg_labels=[kept], scale=1.0,
                                   underlay_map=False)
    raw = cv2.imread(str(synth_root / nusc.get("sample_data", camera)["filename"]))[..., ::-1]
    height, width = raw.shape[:2]
    # the tiles: the views from above in a first row, then the cameras in the dataset's layout, rows of three
    layout = ds.channels["camera_layout"]
    row = next(r for r, channels in enumerate(layout) if "CAM_BACK" in channels)
    x0, y0 = layout[row].index("CAM_BACK") * width, (1 + row) * height
    tile = picture[y0:y0 + height, x0:x0 + width]
    px = np.rint(points[:2].T).astype(int)
    near = np.zeros(raw.shape[:2], np.uint8)
    for u, v in px:
        cv2.circle(near, (int(u), int(v)), 6, 1, -1)
    away = near == 0
    away[-40:, :220] = False  # the caption
    assert away.mean() > 0.5 and (np.abs(tile.astype(int) - raw)[away].max(axis=1) <= 2).mean() > 0.999
    shown = coloring[:, 3] == 1  # the devkit hides the other classes (alpha 0)
    expected = np.rint(coloring[:, :3] * 255).astype(int)
    occupancy = np.zeros(raw.shape[:2], np.int32)
    np.add.at(occupancy, (px[:, 1], px[:, 0]), 1)
    lonely = cv2.boxFilter(occupancy.astype(np.float32), -1, (7, 7), normalize=False)[px[:, 1], px[:, 0]] == 1
    sel = shown & lonely & _inside(px, raw.shape, 4)
    hidden = ~shown & lonely & _inside(px, raw.shape, 4)
    assert sel.sum() > 30 and hidden.sum() > 30
    assert (tile[px[sel, 1], px[sel, 0]] == expected[sel]).all(axis=1).mean() > 0.98
    assert (np.abs(tile[px[hidden, 1], px[hidden, 0]].astype(int) - raw[px[hidden, 1], px[hidden, 0]])
            .max(axis=1) <= 2).mean() > 0.98
    # the lidar's view from above (the first of the two in the top row, which is centred over the camera rows;
    # square, centred in its tile): its kept lidarseg points in their class colours, as the devkit's render_sample
    # draws the lidar with the labels (the other classes' points lie in the boxes drawn over them here)
    assert height == SIZE and width > height and picture.shape[1] == 3 * width
    x0 = (picture.shape[1] - 2 * width) // 2 + (width - height) // 2
    top = picture[:height, x0:x0 + height]
    lidar_px, lonely = _keyframe_top_pixels(nusc, lidar, top.shape)
    labels = np.fromfile(labels_file, np.uint8)
    colours = np.rint(paint_points_label(labels_file, None, nusc.lidarseg_name2idx_mapping, nusc.colormap)[:, :3]
                      * 255).astype(int)
    shown = lonely & (labels == kept)
    assert shown.sum() > 20
    assert (top[lidar_px[shown, 1], lidar_px[shown, 0]] == colours[shown]).all(axis=1).mean() > 0.98


# --- annotation and instance --------------------------------------------------------------------------------------


def test_annotation_camera_is_the_devkits_choice(nusc, ds):
    from nuscenes.utils.geometry_utils import BoxVisibility

    from nuparquet.rendering.pictures.annotation import camera_seeing

    checked = 0
    for ann in nusc.sample_annotation[::7]:
        sample = nusc.get("sample", ann["sample_token"])
        cams = [key for key in sample["data"] if "CAM" in key]
        for level in ("ANY", "ALL"):
            chosen = None
            for cam in cams:
                _, boxes, _ = nusc.get_sample_data(sample["data"][cam], box_vis_level=getattr(BoxVisibility, level),
                                                   selected_anntokens=[ann["token"]])
                if boxes:
                    chosen = sample["data"][cam]
                    break
            if chosen is None:
                with pytest.raises(nuparquet.UsageError, match="is in no camera image"):
                    camera_seeing(ds, ann["sample_token"], ann["token"], level.lower())
            else:
                assert camera_seeing(ds, ann["sample_token"], ann["token"], level.lower()) == chosen
                checked += 1
    assert checked > 20


def test_annotation_picture_draws_the_box_in_the_lidar_view_and_the_camera(nusc, ds, sample):
    from nuscenes.utils.data_classes import LidarPointCloud
    from nuscenes.utils.geometry_utils import view_points

    ann = next(nusc.get("sample_annotation", t) for t in sample["anns"]
               if nusc.get("sample_annotation", t)["num_lidar_pts"] > 10)
    picture = single.render_annotation(ds, ann["token"], scale=0.5)
    lidar_path, boxes, _ = nusc.get_sample_data(sample["data"]["LIDAR_TOP"], selected_anntokens=[ann["token"]])
    corners = view_points(boxes[0].corners(), np.eye(4), False)[:2].T
    x0, y0 = corners.min(axis=0) - 10
    x1, y1 = corners.max(axis=0) + 10
    height = 450  # the camera panel's height at scale 0.5 (900 px images)
    s = height / (y1 - y0)
    width = int(round((x1 - x0) * s))
    assert picture.shape[0] == height and picture.shape[1] == width + 6 + 800

    def pixel(xy):
        return np.c_[(xy[:, 0] - x0) * s - 0.5, (y1 - xy[:, 1]) * s - 0.5]

    panel = picture[:, :width]
    colour = np.array(category_rgb(ann["category_name"]))
    on_box = [(panel[max(0, v - 1):v + 2, max(0, u - 1):u + 2] == colour).all(axis=2).any()
              for u, v in np.rint(pixel(_edge_points(corners))).astype(int)]
    assert np.mean(on_box) > 0.95
    pc = LidarPointCloud.from_file(lidar_path)
    px = np.rint(pixel(pc.points[:2].T)).astype(int)
    keep = _inside(px, panel.shape, 2) & ~((px[:, 0] < 120) & (px[:, 1] > height - 30))
    assert keep.sum() > 20 and (panel[px[keep, 1], px[keep, 0]] != BACKGROUND).any(axis=1).mean() > 0.97


def test_instance_annotation_is_the_devkits_closest(nusc, ds):
    from nuparquet.rendering.pictures.annotation import instance_annotation

    for instance in nusc.instance[::3]:
        closest = [np.inf, None]
        for token in nusc.field2token("sample_annotation", "instance_token", instance["token"]):
            ann = nusc.get("sample_annotation", token)
            pose = nusc.get("ego_pose", nusc.get("sample_data", nusc.get("sample", ann["sample_token"])["data"]
                                                 ["LIDAR_TOP"])["ego_pose_token"])
            distance = np.linalg.norm(np.array(pose["translation"]) - np.array(ann["translation"]))
            if distance < closest[0]:
                closest = [distance, token]
        assert instance_annotation(ds, instance["token"]) == closest[1]
        track = sorted(nusc.field2token("sample_annotation", "instance_token", instance["token"]),
                       key=lambda t: nusc.get("sample", nusc.get("sample_annotation", t)["sample_token"])["timestamp"])
        assert instance_annotation(ds, instance["token"], "middle") == track[len(track) // 2]


# --- the map ------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def nusc_map(synth_root, sample, nusc):
    from nuscenes.map_expansion.map_api import NuScenesMap

    location = nusc.get("log", nusc.get("scene", sample["scene_token"])["log_token"])["location"]
    return NuScenesMap(str(synth_root), location)


def test_map_in_image_fills_the_devkits_projected_polygons(nusc, ds, sample, nusc_map, synth_root):
    """The devkit's render_map_in_image polygons, each computed with its own clipping and projection, are filled;
    outside all of them the image is untouched."""
    from nuscenes.map_expansion.map_api import NuScenesMapExplorer
    from nuscenes.utils.geometry_utils import view_points
    from pyquaternion import Quaternion

    layers = ["road_segment", "lane", "ped_crossing", "walkway", "stop_line", "carpark_area"]
    cam = nusc.get("sample_data", sample["data"]["CAM_FRONT"])
    cs, pose = nusc.get("calibrated_sensor", cam["calibrated_sensor_token"]), nusc.get("ego_pose", cam["ego_pose_token"])
    raw = cv2.imread(str(synth_root / cam["filename"]))[..., ::-1]
    expected = np.zeros(raw.shape[:2], np.uint8)
    t = pose["translation"]
    records = nusc_map.get_records_in_patch((t[0] - 10000, t[1] - 10000, t[0] + 10000, t[1] + 10000), layers)
    drawn = 0
    for layer in layers:
        for token in records[layer]:
            record = nusc_map.get(layer, token)
            for polygon_token in record.get("polygon_tokens", [record.get("polygon_token")]):
                polygon = nusc_map.extract_polygon(polygon_token)
                points = np.vstack((np.array(polygon.exterior.xy), np.zeros((1, len(polygon.exterior.xy[0])))))
                points = Quaternion(pose["rotation"]).rotation_matrix.T @ (points - np.array(t).reshape(-1, 1))
                points = Quaternion(cs["rotation"]).rotation_matrix.T @ (points - np.array(cs["translation"]).reshape(-1, 1))
                if np.all(points[2] < 1e-8):
                    continue
                points = NuScenesMapExplorer._clip_points_behind_camera(points, 1e-8)
                if len(points) == 0 or points.shape[1] < 3:
                    continue
                uv = view_points(points, np.array(cs["camera_intrinsic"]), normalize=True)[:2]
                inside = (uv[0] > 1) & (uv[0] < 1599) & (uv[1] > 1) & (uv[1] < 899)
                import shapely

                if not inside.any() or shapely.Polygon(uv.T).area < 1000:
                    continue
                clipped = shapely.Polygon(uv.T).buffer(0).intersection(shapely.box(-5, -5, 1605, 905))
                for part in shapely.get_parts(clipped):
                    if part.geom_type == "Polygon" and not part.is_empty:
                        cv2.fillPoly(expected, [np.rint(np.asarray(part.exterior.coords)).astype(np.int32)], 1)
                drawn += 1
    assert drawn > 3
    picture = single.render_map_in_image(ds, sample["token"])
    changed = np.abs(picture.astype(int) - raw).max(axis=2) > 3
    legend = np.zeros_like(changed)
    legend[:200, 1300:] = True
    inner = cv2.erode(expected, np.ones((9, 9), np.uint8)).astype(bool) & ~legend
    outer = ~cv2.dilate(expected, np.ones((9, 9), np.uint8)).astype(bool) & ~legend
    assert inner.sum() > 10000 and changed[inner].mean() > 0.99
    assert outer.sum() > 10000 and changed[outer].mean() < 0.01


def test_map_patch_fills_each_layers_polygons(ds, nusc_map, sample, nusc):
    pose = nusc.get("ego_pose", nusc.get("sample_data", sample["data"]["LIDAR_TOP"])["ego_pose_token"])
    x, y = pose["translation"][:2]
    box = (x - 60, y - 40, x + 60, y + 40)
    picture = single.render_map_patch(ds, nusc_map.map_name, box, ["walkway", "lane"], render_legend=False,
                                      render_egoposes_range=False)
    x0, y0, x1, y1 = box[0] - 30, box[1] - 10, box[2] + 30, box[3] + 10  # the devkit's margins
    s = picture.shape[1] / (x1 - x0)
    import shapely

    rng = np.random.default_rng(0)
    probes = np.c_[rng.uniform(x0 + 1, x1 - 1, 3000), rng.uniform(y0 + 1, y1 - 1, 3000)]
    u = np.rint((probes[:, 0] - x0) * s - 0.5).astype(int)
    v = np.rint((y1 - probes[:, 1]) * s - 0.5).astype(int)
    polygons = {layer: shapely.union_all([nusc_map.extract_polygon(r["polygon_token"]) for r in getattr(nusc_map, layer)])
                for layer in ("walkway", "lane")}
    white = (picture[v, u] == 255).all(axis=1)
    for layer, polygon in polygons.items():
        inside = shapely.contains_xy(polygon.buffer(-0.5), probes[:, 0], probes[:, 1])
        tint = np.rint(255 * 0.5 + np.array(MAP_LAYER_RGB[layer]) * 0.5)
        assert inside.sum() > 30 and (~white[inside]).all()
        alone = inside & ~shapely.contains_xy(polygons["lane" if layer == "walkway" else "walkway"].buffer(0.5),
                                               probes[:, 0], probes[:, 1])
        assert (np.abs(picture[v[alone], u[alone]] - tint) <= 1).all()
    outside = ~shapely.contains_xy(shapely.union_all(list(polygons.values())).buffer(0.5), probes[:, 0], probes[:, 1])
    assert outside.sum() > 100 and white[outside].all()


def test_map_patch_outlines_the_box_in_red_dashes(ds, nusc_map, sample, nusc):
    """render_egoposes_range: the box's outline is drawn dashed (the devkit's dash-dotted red rectangle), so along
    its top edge the drawn runs alternate with runs of the map itself."""
    pose = nusc.get("ego_pose", nusc.get("sample_data", sample["data"]["LIDAR_TOP"])["ego_pose_token"])
    x, y = pose["translation"][:2]
    box = (x - 60, y - 40, x + 60, y + 40)
    drawn = single.render_map_patch(ds, nusc_map.map_name, box, ["drivable_area"], render_legend=False)
    plain = single.render_map_patch(ds, nusc_map.map_name, box, ["drivable_area"], render_legend=False,
                                    render_egoposes_range=False)
    x0, y1 = box[0] - 30, box[3] + 10  # the devkit's margins
    s = drawn.shape[1] / (box[2] + 30 - x0)
    u0, u1 = int(round((box[0] - x0) * s)), int(round((box[2] - x0) * s))
    v = int(round((y1 - box[3]) * s - 0.5))
    changed = (drawn[v - 2:v + 3, u0 + 20:u1 - 20] != plain[v - 2:v + 3, u0 + 20:u1 - 20]).any(axis=(0, 2))
    reddish = drawn[v - 2:v + 3, u0 + 20:u1 - 20].astype(int)
    assert ((reddish[..., 0] - reddish[..., 1]) > 100).any(axis=0)[changed].mean() > 0.8  # red where drawn
    runs = np.diff(np.flatnonzero(np.diff(changed.astype(int))))
    assert 0.3 < changed.mean() < 0.8 and len(runs) > 20  # dashes and gaps, not one line
    assert np.median(runs) >= 4


def test_record_picture_names_its_global_and_local_views(ds, nusc_map, monkeypatch):
    """render_record: the whole map captioned "global view" on the left, the close-up "local view" on the right,
    each caption in its picture's top-left corner."""
    from nuparquet.rendering import legend

    captions = []
    drawn = legend.draw_caption
    monkeypatch.setattr(legend, "draw_caption", lambda image, text, **kw: (captions.append((image.shape, text, kw)),
                                                                           drawn(image, text, **kw))[1])
    picture = single.render_record(ds, nusc_map.map_name, "lane", nusc_map.lane[0]["token"])
    assert [(text, kw) for _, text, kw in captions] == [("local view", {"corner": "top-left"}),
                                                       ("global view", {"corner": "top-left"})]
    local, whole = captions[0][0], captions[1][0]  # the close-up first drawn, the whole map on the left
    assert local[0] == whole[0] == picture.shape[0] and picture.shape[1] == whole[1] + 6 + local[1]


def test_layers_draw_traffic_lights_as_the_devkits_arrows_and_name_the_layers_in_order(ds, nusc_map):
    """The devkit's render_layers draws a traffic light as an arrow from its line's first node to its second, in the
    explorer's colour, and a legend entry per layer (its colour); drawn here over a 6 m square around one light."""
    from matplotlib.colors import to_rgb

    assert nusc_map.traffic_light
    xs, ys = nusc_map.extract_line(nusc_map.traffic_light[0]["line_token"]).xy
    start, end = np.array([xs[0], ys[0]]), np.array([xs[1], ys[1]])
    cx, cy = (start + end) / 2
    extent, size = (cx - 3, cy - 3, cx + 3, cy + 3), 1000
    picture = single.render_layers(ds, nusc_map.map_name, ["drivable_area", "traffic_light"], extent=extent,
                                   size_px=size)
    assert picture.shape == (size, size, 3)
    colours = {layer: np.rint(np.array(to_rgb(nusc_map.explorer.color_map[layer])) * 255).astype(int)
               for layer in ("drivable_area", "traffic_light")}
    s = size / 6

    def pixel(xy):
        return np.array([(xy[0] - extent[0]) * s - 0.5, (extent[3] - xy[1]) * s - 0.5])

    a, b = pixel(start), pixel(end)
    assert np.linalg.norm(b - a) > 30
    arrow = (picture == colours["traffic_light"]).all(axis=2)
    arrow[:200, size // 2:] = False  # the legend (top right)
    vs, us = np.nonzero(arrow)
    along = ((np.c_[us, vs] - a) @ (b - a)) / np.dot(b - a, b - a)  # 0 at the first node, 1 at the second
    assert len(us) > 40 and along.min() > -0.1 and along.max() < 1.1  # from the first node to the second ...
    assert (along < 0.15).sum() > 0 and (along > 0.85).sum() > 0
    assert (along > 0.6).sum() > 1.5 * (along < 0.4).sum()  # ... with the head at the second
    # the legend: each layer's swatch, in the order given
    legend = picture[:200, size // 2:]
    rows = {layer: np.nonzero((legend == colour).all(axis=2))[0] for layer, colour in colours.items()}
    assert all(len(r) > 50 for r in rows.values())
    assert rows["drivable_area"].max() < rows["traffic_light"].min()


def test_map_mask_picture_shows_the_devkits_masks(ds, nusc_map, sample, nusc):
    pose = nusc.get("ego_pose", nusc.get("sample_data", sample["data"]["LIDAR_TOP"])["ego_pose_token"])
    patch = (pose["translation"][0], pose["translation"][1], 60.0, 80.0)
    layers = ["drivable_area", "walkway", "lane_divider"]
    masks = nusc_map.get_map_mask(patch, 30, layers, (120, 160))
    picture = single.render_map_mask(ds, nusc_map.map_name, patch, 30, layers, (120, 160), n_row=1, tile_px=120)
    for k, mask in enumerate(masks):
        tile = picture[:, k * (160 + 6):k * (160 + 6) + 160]
        yellow = tile[..., 0] > 128  # viridis' top is yellow, its bottom dark purple
        shown = mask[::-1] == 1  # imshow(origin='lower'): the mask's first row at the bottom
        check = np.ones_like(shown)
        check[:24, :120] = False  # the layer's name
        assert shown[check].any() and (yellow[check] == shown[check]).all()


def test_centerlines_and_ego_poses_are_drawn_where_the_devkit_has_them(ds, nusc_map, nusc):
    picture = single.render_centerlines(ds, nusc_map.map_name)
    x1, y1 = nusc_map.canvas_edge
    s = picture.shape[1] / x1
    poses = np.concatenate([p for p in nusc_map.discretize_centerlines(0.5) if len(p)])[:, :2]
    u, v = np.rint(poses[:, 0] * s - 0.5).astype(int), np.rint((y1 - poses[:, 1]) * s - 0.5).astype(int)
    assert len(u) > 100
    assert np.mean([(picture[b - 1:b + 2, a - 1:a + 2] != 255).any() for a, b in zip(u, v)]) > 0.99

    # render_egoposes_on_fancy_map's poses (its plotting fails under shapely 2 with descartes): every scene at the
    # location in table order, each sample of it in table order (field2token), its LIDAR_TOP ego pose
    logs = [log["token"] for log in nusc.log if log["location"] == nusc_map.map_name]
    expected = np.array([nusc.get("ego_pose", nusc.get("sample_data", nusc.get("sample", token)["data"]["LIDAR_TOP"])
                                  ["ego_pose_token"])["translation"][:2]
                         for scene in nusc.scene if scene["log_token"] in logs
                         for token in nusc.field2token("sample", "scene_token", scene["token"])])
    assert np.array_equal(single.ego_poses_on_map(ds, nusc_map.map_name), expected)
    picture = single.render_egoposes_on_map(ds, nusc_map.map_name)
    low = np.floor(expected.min(axis=0) - 2)
    high = np.ceil(expected.max(axis=0) + 2)
    size = high - low
    if any(size < 30):
        centre, size = (low + high) / 2, np.maximum(size, 30)
        low, high = centre - size / 2, centre + size / 2
    x0 = low[0] - min(size[0] / 4, 50)
    x1, y1 = high[0] + min(size[0] / 4, 50), high[1] + min(size[1] / 4, 10)
    s = picture.shape[1] / (x1 - x0)
    for x, y in expected:
        u, v = int(round((x - x0) * s - 0.5)), int(round((y1 - y) * s - 0.5))
        assert (picture[v, u] == 0).all()  # a black dot on each pose


# --- point colours and legends ------------------------------------------------------------------------------------


def test_point_colours_and_legend_classes_are_the_devkits(nusc, ds, sample):
    from nuscenes.lidarseg.lidarseg_utils import colormap_to_colors, get_labels_in_coloring, paint_points_label
    from nuscenes.panoptic.panoptic_utils import paint_panop_points_label, stuff_cat_ids

    from nuparquet.rendering.pictures.clouds import category_names
    from nuparquet.rendering.point_colors import class_filter, label_rgb, legend_classes

    names = category_names(ds)
    lidar = sample["data"]["LIDAR_TOP"]
    for mode, painter, table in (("lidarseg", paint_points_label, "lidarseg"),
                                 ("panoptic", paint_panop_points_label, "panoptic")):
        path = os.path.join(nusc.dataroot, nusc.get(table, lidar)["filename"])
        labels = (np.fromfile(path, np.uint8) if mode == "lidarseg" else np.load(path)["data"]).astype(np.int64)
        if mode == "panoptic":
            assert (labels % 1000 > 0).any() and (labels // 1000 >= 24).any()  # things and stuff both painted
        expected = painter(path, None, nusc.lidarseg_name2idx_mapping, nusc.colormap)
        assert np.array_equal(label_rgb(labels, mode, names), np.rint(expected[:, :3] * 255).astype(np.uint8))
        for keep in ([24], [17, 24], None):
            filtered = painter(path, keep, nusc.lidarseg_name2idx_mapping, nusc.colormap)
            if keep is not None:
                assert np.array_equal(class_filter(labels, mode, keep, len(names)), filtered[:, 3] == 1)
        if mode == "lidarseg":  # no filter: the classes among the points shown (render_pointcloud_in_image)
            colours = paint_points_label(path, None, nusc.lidarseg_name2idx_mapping, nusc.colormap)
            legend = colormap_to_colors(nusc.colormap, nusc.lidarseg_name2idx_mapping)
            assert legend_classes(labels, mode, None, names) == get_labels_in_coloring(legend, colours[:, :3])
        else:  # panoptic: the stuff classes, of the filter when one is given
            assert legend_classes(labels, mode, None, names) == stuff_cat_ids(len(nusc.lidarseg_name2idx_mapping))
            assert legend_classes(labels, mode, [17, 24, 25], names) == [24, 25]


# --- map drawing details --------------------------------------------------------------------------------------------

# the devkit draws map lines with plt.plot's default width (rcParams lines.linewidth: 1.5 pt), 2.08 px at matplotlib's
# default 100 dpi, on a figure about as many pixels wide as the pictures here (render_centerlines: canvas_edge / 200
# inches at 100 dpi, 1000 px for a 2 km map). OpenCV's anti-aliased lines ink wider than their thickness (1: 1.35 px,
# 2: 3.4 px, 3: 5.4 px); the pictures' lines must be at least as visible as the devkit's and at most twice as wide.
DEVKIT_LINE_PX = 1.5 * 100 / 72


def _line_width_px(image_rgb: np.ndarray, length_px: float) -> float:
    """The mean width of the one line drawn over white in `image_rgb`: its ink (each pixel's share of the line's
    colour, the darkest pixel's, anti-aliasing included) over its length."""
    total = image_rgb.astype(np.float64).sum(axis=2)
    ink = (765 - total) / (765 - total.min())
    return float(ink.sum() / length_px)


def test_map_lines_and_centrelines_are_at_least_as_wide_as_the_devkits_line_and_at_most_twice(ds, nusc_map):
    """A lane divider (draw_layers, as render_map_patch and render_layers draw line layers) and a lane's centreline
    (render_centerlines) are each drawn at least as wide as the devkit's plt.plot line and at most twice as wide."""
    import shapely

    from nuparquet.rendering.map_canvas import MapCanvas
    from nuparquet.rendering.pictures.map_views import draw_layers

    divider = max(nusc_map.lane_divider, key=lambda r: nusc_map.extract_line(r["line_token"]).length)
    line = nusc_map.extract_line(divider["line_token"])
    cx, cy = np.asarray(line.interpolate(0.5, normalized=True).coords)[0]
    canvas = MapCanvas.create((cx - 2, cy - 2, cx + 2, cy + 2), 400)  # 100 px/m
    draw_layers(canvas, ds.map(nusc_map.map_name), ["lane_divider"], 1.0, tokens=[divider["token"]])
    length_px = line.intersection(canvas.box).length * canvas.px_per_m
    assert length_px > 300
    assert DEVKIT_LINE_PX <= _line_width_px(canvas.image, length_px) <= 2 * DEVKIT_LINE_PX

    lanes = [p[:, :2] for p in nusc_map.discretize_centerlines(0.5) if len(p) > 4]
    centre = max(lanes, key=len)
    cx, cy = centre[len(centre) // 2]
    extent = (cx - 1, cy - 1, cx + 1, cy + 1)  # 2 m square: no other lane's centreline (lanes are ~3.5 m apart)
    picture = single.render_centerlines(ds, nusc_map.map_name, extent=extent, size_px=400)  # 200 px/m
    drawn = [shapely.LineString(p).intersection(shapely.box(*extent)).length for p in lanes]
    assert sum(d > 0 for d in drawn) == 1
    assert DEVKIT_LINE_PX <= _line_width_px(picture, max(drawn) * 200) <= 2 * DEVKIT_LINE_PX


def test_a_layer_without_records_has_no_shapes(ds, nusc_map):
    """A map with no record of a layer (a location without walkways): layer_geometries gives no shape, as for a box
    no record meets; the records of a layer that has them are the devkit's, in file order."""
    import shapely

    from nuparquet.map.lookup import _Layer
    from nuparquet.map.queries import MapLayers
    from nuparquet.rendering.map_canvas import layer_geometries

    def wkt(geometry) -> str:
        return shapely.to_wkt(shapely.normalize(geometry), rounding_precision=3)

    layers = MapLayers.open(ds, nusc_map.map_name)  # a map of its own: ds.map's is shared with the other tests
    assert [wkt(g) for g in layer_geometries(layers, "walkway")] == [
        wkt(nusc_map.extract_polygon(r["polygon_token"])) for r in nusc_map.walkway]
    far = shapely.box(-1e6, -1e6, -1e6 + 1, -1e6 + 1)
    assert len(layer_geometries(layers, "walkway", far)) == 0
    layers.layers["walkway"] = _Layer(np.empty(0, object), np.empty(0, object))
    for box in (None, far):
        shapes = layer_geometries(layers, "walkway", box)
        assert shapes.shape == (0,), box


def test_clipping_behind_the_camera_is_the_devkits(nusc):
    """clip_behind_camera walks a polygon's edges as the devkit's _clip_points_behind_camera: points behind the near
    plane dropped, each crossing edge ending on it; a polygon wholly behind gives no point, as a (3, 0) array."""
    from nuscenes.map_expansion.map_api import NuScenesMapExplorer

    from nuparquet.rendering.pictures.map_in_image import NEAR_PLANE_M, clip_behind_camera

    rng = np.random.default_rng(5)
    for _ in range(50):
        points = np.c_[rng.uniform(-5, 5, (6, 2)), rng.uniform(-3, 6, 6)].T  # (3, 6), some behind the camera
        expected = NuScenesMapExplorer._clip_points_behind_camera(points, NEAR_PLANE_M)
        np.testing.assert_allclose(clip_behind_camera(points), expected, atol=1e-12)
    behind = np.array([[0.0, 1.0, 1.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -0.5]])
    assert NuScenesMapExplorer._clip_points_behind_camera(behind, NEAR_PLANE_M).size == 0
    assert clip_behind_camera(behind).shape == (3, 0)


def test_lidar_points_beyond_axes_limit_are_coloured_by_distance_over_limit_root_two_like_the_devkit(nusc, ds, sample):
    """render_sample_data colours lidar points by `min(1, dists / axes_limit / sqrt(2))` (then scatter's min-max
    scaling through viridis): a point between axes_limit and axes_limit * sqrt(2) from the sensor (the view's
    corners) takes its own colour, not the saturated end of the map. Checked at isolated points of that band, in
    a view narrow enough to hold many of them."""
    from scipy.spatial import cKDTree

    from nuparquet.rendering.point_colors import scalar_rgb
    from nuscenes.utils.data_classes import LidarPointCloud

    limit = 12.0
    token = sample["data"]["LIDAR_TOP"]
    picture = single.render_sample_data(ds, token, with_anns=False, underlay_map=False, axes_limit=limit)
    points_xy, _, _ = _devkit_flat_view(nusc, token, 1)
    pc = LidarPointCloud.from_file(str(nusc.get_sample_data_path(token)))
    dists = np.sqrt(np.sum(pc.points[:2, :] ** 2, axis=0))
    expected = scalar_rgb(np.minimum(1, dists / limit / np.sqrt(2)))  # scatter(c=colors): min-max over the cloud
    s = SIZE / (2 * limit)
    px = np.c_[(points_xy[:, 0] + limit) * s - 0.5, (limit - points_xy[:, 1]) * s - 0.5]
    neighbours = cKDTree(px).query(px, k=2)[0][:, 1]
    band = (dists > limit * 1.02) & (dists < limit * np.sqrt(2) * 0.98)
    keep = band & (neighbours > 4) & _inside(px, picture.shape, 4) & _away_from_corners(px, picture.shape)
    assert keep.sum() > 20
    u, v = np.rint(px[keep]).astype(int).T
    drawn = picture[v, u].astype(int)
    assert len(np.unique(expected[keep], axis=0)) > 5  # many colours in the band: not one saturated end
    close = np.abs(drawn - expected[keep].astype(int)).max(axis=1) <= 2
    assert close.mean() > 0.9
