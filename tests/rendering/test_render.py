"""Rendering: segment geometry, clipping, drawing order, mosaic time matching, and overlays that land on the
cuboids the synthetic generator painted into its camera images."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import nuparquet
from nuparquet.geometry import Cameras, scale_pixels
from nuparquet.frames.boxes import frame_boxes
from nuparquet.rendering.palette import category_rgb
from nuparquet.frames.projection import project_boxes
from nuparquet.frames.poses import cameras_from_frames
from nuparquet.rendering import draw
from nuparquet.rendering.mosaic import match_frames_by_time, time_steps_us
from nuparquet.rendering.overlay import build_overlay, segments_touch_image
from nuparquet.rendering.video.pipeline import RenderOptions, render
from nuparquet.rendering.video.scene import load_scene

K = np.array([[1000.0, 0.0, 800.0], [0.0, 1000.0, 450.0], [0.0, 0.0, 1.0]])
SIZE = np.array([[1600.0, 900.0]])


def _camera(intrinsic=K) -> Cameras:
    """One 1600x900 camera at the global origin (global = ego = camera frame) with intrinsics `intrinsic`."""
    return Cameras(np.eye(4)[None], np.eye(4)[None], intrinsic[None], SIZE.copy(), np.ones((1, 2)))


def _clip(corners, near_m=0.1):
    """Near-plane clipping of a box's 14 drawn segments by a camera with intrinsics K."""
    return _camera().clip_segments(corners[:, draw.BOX_SEGMENT_CORNERS], near_m)


def _unit_box_corners(center_cam_m) -> np.ndarray:
    """(1, 8, 3) corners of a 2 m cube at `center_cam_m` in the camera frame, in devkit corner order."""
    from nuparquet.geometry import box_corners

    return box_corners(np.array([center_cam_m], dtype=float), np.array([[2.0, 2.0, 2.0]]), np.array([[1.0, 0, 0, 0]]))


# --- geometry of the drawing --------------------------------------------------------------------------------


def test_camera_corners_from_pixels_inverts_the_projection():
    corners = _unit_box_corners([1.0, -0.5, 12.0])[0]
    projected = corners @ K.T
    pixels = projected[:, :2] / projected[:, 2:]
    back = _camera().unproject(pixels[None], corners[None, :, 2])[0]
    np.testing.assert_allclose(back, corners, atol=1e-9)


def test_clip_leaves_a_box_in_front_of_the_camera_unchanged():
    corners = _unit_box_corners([0.5, 0.0, 10.0])
    segments, keep = _clip(corners)
    projected = corners[0] @ K.T
    expected = draw.box_segments_px((projected[:, :2] / projected[:, 2:])[None])
    assert keep.all()
    np.testing.assert_allclose(segments, expected, atol=1e-9)


def test_clip_cuts_edges_at_the_near_plane_and_drops_edges_behind_it():
    # Hand-made corners: 0, 3, 4, 7 in front of the camera, 1, 2, 5, 6 behind it.
    corners = np.array([[[0, 0, 2.0], [0, 0, -1.0], [1, 0, -1.0], [1, 0, 2.0], [0, 1, 2.0], [0, 1, -2.0], [1, 1, -2.0], [1, 1, 2.0]]])
    segments, keep = _clip(corners, near_m=0.1)
    # Segment 0 (corners 0 -> 1) crosses the plane: its far end is at z = 0.1 on the line, projected.
    t = (0.1 - 2.0) / (-1.0 - 2.0)
    crossing = np.array([0, 0, 2.0]) + t * (np.array([0, 0, -1.0]) - np.array([0, 0, 2.0]))
    expected_px = (K @ crossing)[:2] / 0.1
    assert keep[0, 0]
    np.testing.assert_allclose(segments[0, 0, 1], expected_px, atol=1e-9)
    # Segment 1 (corners 1 -> 2) lies entirely behind the plane.
    assert not keep[0, 1]
    assert np.isnan(segments[0, 1]).all()


def test_scale_pixels_keeps_pixel_centres_of_a_resized_image():
    # 2x downscale with area averaging: source pixels 0 and 1 become destination pixel 0, whose centre is at
    # source coordinate 0.5; the last destination pixel (799) covers 1598 and 1599, centre 1598.5.
    np.testing.assert_allclose(scale_pixels([[0.5, 0.5], [1598.5, 898.5]], 0.5), [[0.0, 0.0], [799.0, 449.0]])
    image = np.zeros((900, 1600), np.uint8)
    image[600:602, 1000:1002] = 255  # a 2x2 block centred at (1000.5, 600.5)
    small = cv2.resize(image, (800, 450), interpolation=cv2.INTER_AREA)
    v, u = np.argwhere(small == 255)[0]
    np.testing.assert_allclose(scale_pixels([[1000.5, 600.5]], 0.5)[0], [u, v])


def test_boxes_drawn_later_cover_boxes_drawn_earlier():
    image = np.zeros((200, 200, 3), np.uint8)
    square = np.array([[[50, 50], [150, 50], [150, 150], [50, 150]] * 2], dtype=float)  # (1, 8, 2)
    segments = draw.box_segments_px(np.concatenate([square, square]))
    draw.draw_boxes(image, segments, [(255, 0, 0), (0, 255, 0)], widths=(3, 3, 1), antialias=False)
    assert tuple(image[50, 100]) == (0, 255, 0)  # BGR: the second (green) box is on top


def test_draw_points_writes_near_points_over_far_ones():
    image = np.zeros((10, 10, 3), np.uint8)
    draw.draw_points(image, [[5, 5], [5, 5]], [1.0, 50.0], size_px=1, max_depth_m=60)
    near = cv2.applyColorMap(np.array([[round(255 * (1 - 1 / 60))]], np.uint8), cv2.COLORMAP_TURBO)[0, 0]
    assert tuple(image[5, 5]) == tuple(near)


def test_short_labels():
    assert draw.short_category("vehicle.car") == "car"
    assert draw.short_category("human.pedestrian.adult") == "pedestrian.adult"
    assert draw.short_category("animal") == "animal"
    assert draw.short_track("a1b2c3d4e5") == "a1b2c3"


# --- mosaic --------------------------------------------------------------------------------------------------


def _devkit_walk(timestamps_us, start_index, first_us, last_us, freq_hz):
    """NuScenesExplorer.render_scene's frame choice, transcribed: walk each camera's `next` chain forward while
    the frame is older than the output time."""
    chosen = []
    index = start_index
    current_time = first_us
    time_step = 1 / freq_hz * 1e6
    while current_time < last_us:
        current_time += time_step
        while timestamps_us[index] < current_time and index + 1 < len(timestamps_us):
            index += 1
        chosen.append(index)
    return chosen


@pytest.mark.parametrize("freq_hz", [2.0, 10.0, 12.0])
def test_mosaic_time_matching_equals_the_devkit_walk(freq_hz):
    rng = np.random.default_rng(3)
    timestamps = np.cumsum(rng.integers(70_000, 95_000, size=250)) + 1_500_000_000_000_000
    start, first, last = 5, int(timestamps[5]) - 3_000, int(timestamps[230])
    times = time_steps_us(first, last, freq_hz)
    got = match_frames_by_time(timestamps, start, times)
    assert got.tolist() == _devkit_walk(timestamps, start, first, last, freq_hz)


# --- overlays on synthetic images ----------------------------------------------------------------------------


def _scene_boxes(out, channel="CAM_FRONT"):
    """Keyframes of one synthetic scene's channel and their projected (ANY-visible) boxes."""
    ds = nuparquet.open(out)
    scene = ds.scan("scenes").select("name").collect()["name"].sort()[0]
    loaded = load_scene(ds, scene, [channel])
    projected = project_boxes(loaded.cameras, loaded.annotations, loaded.samples, visibility="any")
    return ds, scene, loaded, projected


def _tile_cameras(loaded, size):
    return cameras_from_frames(loaded.cameras).resized_to(size)


def _boxes(loaded):
    return frame_boxes(loaded.cameras, loaded.annotations, loaded.samples)


def _edge_samples(corners_px, toward_centre_px):
    """Points along each of the 12 cuboid edges (t in 0.2..0.8), moved `toward_centre_px` pixels towards the
    box's projected centre. Returns (M, 12 * 7, 2)."""
    edges = draw.box_segments_px(corners_px)[:, :12]  # (M, 12, 2, 2)
    t = np.linspace(0.2, 0.8, 7)[None, None, :, None]
    points = edges[:, :, None, 0] + t * (edges[:, :, None, 1] - edges[:, :, None, 0])  # (M, 12, 7, 2)
    centre = corners_px.mean(axis=1)[:, None, None, :]
    direction = centre - points
    length = np.linalg.norm(direction, axis=-1, keepdims=True)
    points = points + toward_centre_px * direction / np.maximum(length, 1e-9)
    return points.reshape(len(corners_px), -1, 2)


def _topmost_box(shape, corners_px, distance_m) -> np.ndarray:
    """(H, W) index of the box whose filled hull is nearest at each pixel (-1: none), painted far to near."""
    owner = np.full(shape, -1, dtype=np.int32)
    for index in np.argsort(-distance_m, kind="stable"):  # test reference: one hull per box
        hull = cv2.convexHull(np.rint(corners_px[index] * 16).astype(np.int32))
        cv2.fillConvexPoly(owner, hull, int(index), cv2.LINE_8, 4)
    return owner


def _colour_match_fraction(images_by_row, projected, occluders=None, shift_px=(0.0, 0.0), toward_centre_px=4.0,
                           tolerance=40.0):
    """Fraction of points sampled along the projected edges of `projected`'s boxes whose pixel in the image has
    the box's category colour. With `occluders` (every box in front of the camera), points where a nearer
    box covers the edge are not counted."""
    matched = total = 0
    for row, image in images_by_row.items():
        rows = np.flatnonzero(projected.frame_index == row)
        if len(rows) == 0:
            continue
        corners = projected.corners_px[rows] + np.asarray(shift_px)
        # Only boxes large enough that "inside the edge" is inside the painted cuboid.
        extent = corners.max(axis=1) - corners.min(axis=1)
        big = (extent > 12).all(axis=1)
        samples = _edge_samples(corners[big], toward_centre_px)
        colours_bgr = np.array([category_rgb(n)[::-1] for n in projected.category_name[rows][big]], float)
        u = np.rint(samples[..., 0]).astype(int)
        v = np.rint(samples[..., 1]).astype(int)
        inside = (u >= 0) & (u < image.shape[1]) & (v >= 0) & (v < image.shape[0])
        u, v = np.clip(u, 0, image.shape[1] - 1), np.clip(v, 0, image.shape[0] - 1)
        if occluders is not None:
            mine = np.flatnonzero(occluders.frame_index == row)
            owner = _topmost_box(image.shape[:2], occluders.corners_px[mine] + np.asarray(shift_px), occluders.distance_m[mine])
            token_of_owner = occluders.annotation_token[mine]
            on_top = owner[v, u]
            inside &= (on_top >= 0) & (token_of_owner[np.maximum(on_top, 0)] == projected.annotation_token[rows][big][:, None])
        pixels = image[v, u].astype(float)
        distance = np.linalg.norm(pixels - colours_bgr[:, None, :], axis=-1)
        matched += int(((distance < tolerance) & inside).sum())
        total += int(inside.sum())
    return matched, total


def test_projected_box_edges_lie_on_the_painted_cuboids(synth_out):
    ds, scene, loaded, projected = _scene_boxes(synth_out)
    assert len(projected) > 0
    images = {
        row: cv2.imread(str(f"{ds.dataroot}/{name}"))
        for row, name in enumerate(loaded.cameras["filename"].to_list())
    }
    # Every box in front of the camera can hide another (the generator paints them all, far to near).
    every = project_boxes(loaded.cameras, loaded.annotations, loaded.samples, visibility="none")
    occluders = every.take(every.in_front)
    # Edges are sampled 4 px inside the projected outline: the generator outlines each silhouette in a darker
    # shade and JPEG blurs the boundary.
    matched, total = _colour_match_fraction(images, projected, occluders)
    assert total > 200
    assert matched / total > 0.95
    # The check discriminates: the same boxes moved 30 px sideways mostly miss their cuboids.
    shifted, shifted_total = _colour_match_fraction(images, projected, occluders, shift_px=(30.0, 0.0))
    assert shifted / shifted_total < 0.6


def test_rendered_frames_carry_the_category_colour_along_the_box_edges(synth_out, tmp_path):
    ds, scene, loaded, projected = _scene_boxes(synth_out)
    result = render(
        ds, scene, None, RenderOptions(channel="CAM_FRONT", frame_format="png", scale=1.0, labels="none"), frames_dir=tmp_path
    )
    assert result.frames_written == loaded.cameras.height
    drawn = {row: cv2.imread(str(tmp_path / f"{row:05d}.png")) for row in range(loaded.cameras.height)}
    # Exactly on the edges (no nudge), in the lossless PNG output: the drawn lines themselves.
    matched, total = _colour_match_fraction(drawn, projected, toward_centre_px=0.0, tolerance=10.0)
    assert total > 200
    assert matched / total > 0.9


def test_overlay_draws_boxes_far_to_near_within_each_frame(synth_out):
    ds, scene, loaded, projected = _scene_boxes(synth_out)
    overlay = build_overlay(_tile_cameras(loaded, (1600, 900)), _boxes(loaded))
    assert overlay.row_start[-1] == len(projected)
    for row in range(loaded.cameras.height):
        start, stop = overlay.row_start[row], overlay.row_start[row + 1]
        # Distance of the drawn boxes' centres: recovered from the segments is awkward, so compare against the
        # projection sorted by distance, descending.
        rows = np.flatnonzero(projected.frame_index == row)
        expected = projected.corners_px[rows][np.argsort(-projected.distance_m[rows], kind="stable")]
        np.testing.assert_allclose(overlay.segments_px[start:stop], draw.box_segments_px(expected))


def test_clip_mode_draws_a_box_partly_behind_the_camera_that_the_devkit_mode_drops():
    corners = _unit_box_corners([0.0, 0.0, 0.5])  # spans z = -0.5 .. 1.5: straddles the near plane
    assert not (corners[..., 2] > 0.1).all()  # devkit box_in_image: not in front, so never drawn
    segments, keep = _clip(corners)
    assert keep.any() and not keep.all()
    assert segments_touch_image(segments, keep, SIZE).all()
    image = np.zeros((900, 1600, 3), np.uint8)
    draw.draw_boxes(image, segments, [(255, 158, 0)], keep=keep)
    assert (image == (0, 158, 255)).all(axis=-1).sum() > 100


def test_clip_mode_keeps_every_box_the_devkit_mode_draws(synth_out):
    ds, scene, loaded, _ = _scene_boxes(synth_out)
    size = (1600, 900)
    clipped = build_overlay(_tile_cameras(loaded, size), _boxes(loaded), clip=True)
    devkit = build_overlay(_tile_cameras(loaded, size), _boxes(loaded))
    assert np.all(np.diff(clipped.row_start) >= np.diff(devkit.row_start))
    assert np.isfinite(clipped.segments_px[clipped.keep]).all()


def test_boxes_are_antialiased_unless_told_not_to():
    """draw_boxes' default (antialias=True) draws OpenCV's anti-aliased lines: a slanted edge in pure red on black
    leaves pixels of partial red; antialias=False draws hard 8-connected lines, every pixel red or black."""
    corners = np.array([[[20, 30], [170, 60], [180, 170], [30, 150]] * 2], dtype=float)  # slanted edges
    segments = draw.box_segments_px(corners)
    smooth = draw.draw_boxes(np.zeros((200, 200, 3), np.uint8), segments, [(255, 0, 0)])
    hard = draw.draw_boxes(np.zeros((200, 200, 3), np.uint8), segments, [(255, 0, 0)], antialias=False)
    for image in (smooth, hard):
        assert (image[..., :2] == 0).all() and (image[..., 2] == 255).sum() > 300  # red (BGR) lines on black
    assert set(np.unique(hard[..., 2]).tolist()) == {0, 255}
    partial = (smooth[..., 2] > 0) & (smooth[..., 2] < 255)
    assert partial.sum() > 200


def test_a_box_touches_the_image_only_in_front_of_the_camera_and_overlapping_it_on_both_axes():
    """`segments_touch_image` culls a box unless some segment is kept (in front) and the kept end points' box
    overlaps the image in x and in y; each test on its own edge (a box left of, above, below the image, and one
    whose segments are all behind the camera while their y span crosses the image)."""
    inside = np.array([[[[100.0, 100.0], [200.0, 200.0]]]])
    keep = np.ones((1, 1), bool)
    cases = {
        "inside": (inside, keep, True),
        "left of it": (inside - [300.0, 0.0], keep, False),
        "right of it": (inside + [1600.0, 0.0], keep, False),
        "above it": (inside - [0.0, 300.0], keep, False),
        "below it": (inside + [0.0, 900.0], keep, False),
        "on the last pixel": (np.array([[[[1599.0, 899.0], [1700.0, 1000.0]]]]), keep, True),
        "behind the camera": (inside, np.zeros((1, 1), bool), False),
        "behind, left of it": (inside - [300.0, 0.0], np.zeros((1, 1), bool), False),
    }
    for name, (segments, kept, expected) in cases.items():
        assert segments_touch_image(segments, kept, SIZE).tolist() == [expected], name


def test_box_labels_follow_the_labels_option_through_the_scene_pipeline(synth_out, tmp_path):
    """`--labels none` draws the outlines only, `category` adds the names: the option reaches the overlay."""
    ds, scene, loaded, _ = _scene_boxes(synth_out)
    frames = {}
    for labels in ("none", "category"):
        render(ds, scene, None, RenderOptions(channel="CAM_FRONT", frame_format="png", scale=0.5, labels=labels),
               frames_dir=tmp_path / labels)
        frames[labels] = [cv2.imread(str(p)) for p in sorted((tmp_path / labels).glob("*.png"))]
    assert len(frames["none"]) == len(frames["category"]) == loaded.cameras.height
    changed = sum(int((a != b).any(axis=2).sum()) for a, b in zip(frames["none"], frames["category"]))
    assert changed > 100  # the label texts
