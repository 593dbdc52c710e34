"""The fused pair projection (`geometry.box_projection`): the compiled kernel (numba) against the numpy columns on
irregular inputs, bit for bit, and both against the step-by-step numpy path (`boxes_in_cameras` + `perspective` +
`box_visibility`, which the devkit parity tests pin) and against hand-worked values; the fallback when numba
cannot load; which implementation `kernel=` picks; and that small projections never load numba."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import warnings

import numpy as np
import pytest

from nuparquet.geometry import Cameras, box_half_axes, box_visibility, perspective, rigid_transforms
from nuparquet.geometry import box_projection, compiled
from nuparquet.geometry.box_projection import COMPILED_MIN_PAIRS, project_pairs

K = np.array([[1266.4, 0.0, 816.3], [0.0, 1266.4, 491.5], [0.0, 0.0, 1.0]])


def _unit_quaternions(rng, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _cameras(rng, f: int, *, scale=None, far_m: float = 500.0) -> Cameras:
    """F cameras at random poses around the map (ego within `far_m` of the origin) with random mounts."""
    global_from_ego = rigid_transforms(rng.uniform(-far_m, far_m, (f, 3)), _unit_quaternions(rng, f))
    ego_from_camera = rigid_transforms(rng.normal(0.0, 1.5, (f, 3)), _unit_quaternions(rng, f))
    cameras = Cameras.from_poses(global_from_ego, ego_from_camera, np.broadcast_to(K, (f, 3, 3)),
                                 np.tile([1600.0, 900.0], (f, 1)))
    return cameras if scale is None else cameras.resized(scale)


def _boxes_near(rng, cameras: Cameras, frame: np.ndarray, spread_m: float) -> np.ndarray:
    """Box centres around each pair's camera (so some are in view, some beside, some behind it)."""
    camera_position = np.linalg.inv(cameras.camera_from_global)[:, :3, 3]
    return camera_position[frame] + rng.normal(0.0, spread_m, (len(frame), 3))


def _both(cameras, frame, translation, half_axes, axes_row):
    numpy_result = project_pairs(cameras, frame, translation, half_axes, axes_row, kernel="numpy")
    compiled_result = project_pairs(cameras, frame, translation, half_axes, axes_row, kernel="compiled")
    return numpy_result, compiled_result


def _assert_same_bits(a, b) -> None:
    for field in dataclasses.fields(a):
        x, y = getattr(a, field.name), getattr(b, field.name)
        assert x.shape == y.shape and x.dtype == y.dtype, field.name
        # equal_nan: a corner at depth 0 projects to nan in both; everything else must be the same number
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), field.name
        if x.dtype.kind == "f":  # same bits, so the same signs of zero and the same infinities too
            assert np.array_equal(np.signbit(x), np.signbit(y)), field.name


def _stepwise(cameras: Cameras, frame, translation, half_axes, axes_row):
    """The step-by-step numpy path the parity tests pin (centres moved by transform, corners from half-axes)."""
    from nuparquet.geometry import corners_from_half_axes

    ego = cameras.ego_from_global[frame]
    center_ego = np.einsum("mij,mj->mi", ego[:, :3, :3], translation) + ego[:, :3, 3]
    cam = cameras.camera_from_ego[frame]
    center_camera = np.einsum("mij,mj->mi", cam[:, :3, :3], center_ego) + cam[:, :3, 3]
    rotation = cam[:, :3, :3] @ ego[:, :3, :3]
    corners = corners_from_half_axes(half_axes[axes_row] @ np.swapaxes(rotation, -1, -2)) + center_camera[:, None]
    corners_px, depths = perspective(cameras.image_from_camera[frame], corners)
    corner_visible, in_front, visible = box_visibility(corners_px, depths, cameras.size_px[frame],
                                                       cameras.scale[frame])
    return center_ego, center_camera, corners, corners_px, corner_visible, in_front, visible


@pytest.mark.parametrize("scale", [None, 0.5, (0.37, 0.61)])
def test_compiled_kernel_gives_the_numpy_columns_bits_and_the_stepwise_numbers(scale):
    rng = np.random.default_rng(26)
    cameras = _cameras(rng, 40, scale=scale)
    frame = rng.integers(0, 40, 5_000)  # cameras interleaved, not grouped: the kernel reloads per change
    annotations = 700
    half_axes = box_half_axes(rng.uniform(0.2, 12.0, (annotations, 3)), _unit_quaternions(rng, annotations))
    axes_row = rng.integers(0, annotations, len(frame))  # one row seen by several pairs, as six cameras see a box
    translation = _boxes_near(rng, cameras, frame, 25.0)
    ours, theirs = _both(cameras, frame, translation, half_axes, axes_row)
    _assert_same_bits(ours, theirs)
    # the data reach every case: in view, beside, behind, straddling the near plane
    assert 0 < ours.visible.sum() < len(frame) and 0 < ours.in_front.sum() < len(frame)
    assert (ours.corners_camera_m[..., 2] < 0).all(axis=1).any() and (ours.corner_visible.sum(axis=1) == 8).any()
    center_ego, center_camera, corners, corners_px, corner_visible, in_front, visible = _stepwise(
        cameras, frame, translation, half_axes, axes_row)
    np.testing.assert_allclose(ours.center_ego_m, center_ego, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.center_camera_m, center_camera, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.corners_camera_m, corners, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(ours.depths, ours.corners_camera_m[..., 2])
    shown = visible & (np.abs(corners[..., 2]) > 1e-3).all(axis=1)
    np.testing.assert_allclose(ours.corners_px[shown], corners_px[shown], rtol=1e-12, atol=1e-6)
    # the flags may differ only where a corner sits within rounding of a limit: none does in this data
    np.testing.assert_array_equal(ours.corner_visible, corner_visible)
    np.testing.assert_array_equal(ours.in_front, in_front)
    np.testing.assert_array_equal(ours.visible, visible)
    np.testing.assert_allclose(ours.distance_m, np.linalg.norm(center_camera, axis=1), rtol=1e-12, atol=0)


def test_no_pairs_and_no_cameras():
    rng = np.random.default_rng(1)
    empty = np.zeros(0, dtype=np.int64)
    for cameras in (_cameras(rng, 3), _cameras(rng, 0)):
        for result in _both(cameras, empty, np.zeros((0, 3)), np.zeros((0, 3, 3)), empty):
            assert result.corners_camera_m.shape == (0, 8, 3) and result.corners_px.shape == (0, 8, 2)
            assert result.corner_visible.shape == (0, 8) and result.visible.shape == (0,)
            assert result.depths.shape == (0, 8)


def test_one_box_straight_ahead_worked_by_hand():
    """Camera at the origin looking along global x (z forward, x right, y down); a 2 x 4 x 1.5 m box (w, l, h)
    at 10 m, heading along x: its centre projects to the principal point, its faces lie at 8 and 12 m."""
    camera_mount = rigid_transforms([0.0, 0.0, 0.0], [0.5, -0.5, 0.5, -0.5])  # ego x forward -> camera z
    cameras = Cameras.from_poses(np.eye(4)[None], camera_mount[None], K[None], [[1600.0, 900.0]])
    half_axes = box_half_axes([[2.0, 4.0, 1.5]], [[1.0, 0.0, 0.0, 0.0]])
    for result in _both(cameras, [0], [[10.0, 0.0, 0.0]], half_axes, [0]):
        np.testing.assert_allclose(result.center_ego_m, [[10.0, 0.0, 0.0]], atol=1e-12)
        np.testing.assert_allclose(result.center_camera_m, [[0.0, 0.0, 10.0]], atol=1e-12)
        np.testing.assert_allclose(np.sort(np.unique(result.depths.round(12))), [8.0, 12.0])
        # corner 0 (front face, top left seen from the front: box +x, +y, +z = ego (12, 1, 0.75)) is camera
        # (-1, -0.75, 12): the box heads away, so its front face is the far one
        np.testing.assert_allclose(result.corners_camera_m[0, 0], [-1.0, -0.75, 12.0], atol=1e-12)
        np.testing.assert_allclose(result.corners_px[0, 0], [816.3 - 1266.4 / 12, 491.5 - 0.75 * 1266.4 / 12],
                                   rtol=1e-14)
        np.testing.assert_allclose(result.corners_camera_m[0, 4], [-1.0, -0.75, 8.0], atol=1e-12)
        assert result.corner_visible.all() and result.in_front[0] and result.visible[0]
        assert result.distance_m[0] == pytest.approx(10.0, abs=1e-12)
    _assert_same_bits(*_both(cameras, [0], [[10.0, 0.0, 0.0]], half_axes, [0]))


def test_boxes_behind_the_camera_and_on_the_limits():
    """Behind the camera: mirrored pixels, nothing visible; a corner at depth exactly 0: inf/nan in both; the
    strict 1 m and 0.1 m limits (exact in floating point: 0/+-1 rotations)."""
    camera_mount = rigid_transforms([0.0, 0.0, 0.0], [0.5, -0.5, 0.5, -0.5])
    cameras = Cameras.from_poses(np.eye(4)[None], camera_mount[None], K[None], [[1600.0, 900.0]])
    identity = [1.0, 0.0, 0.0, 0.0]
    sizes = [[2.0, 4.0, 1.5], [2.0, 4.0, 1.5], [0.5, 1.0, 0.5], [0.5, 0.25, 0.5], [2.0, 2.0, 2.0]]
    centres = [[-10.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.225, 0.0, 0.0], [1.0, 0.0, 0.0]]
    half_axes = box_half_axes(sizes, [identity] * 5)
    numpy_result, compiled_result = _both(cameras, [0] * 5, centres, half_axes, np.arange(5))
    _assert_same_bits(numpy_result, compiled_result)
    for r in (numpy_result, compiled_result):
        assert (r.depths[0] < 0).all() and not r.corner_visible[0].any() and not r.visible[0]
        assert not r.in_front[1] and not r.visible[1]  # straddles the camera
        np.testing.assert_array_equal(np.unique(r.depths[2]), [1.0, 2.0])
        np.testing.assert_array_equal(r.corner_visible[2], r.depths[2] == 2.0)  # 1.0 m is not > 1 m
        assert r.in_front[2] and r.visible[2]
        np.testing.assert_array_equal(np.unique(r.depths[3]), [0.1, 0.35])
        assert not r.in_front[3]  # 0.1 m is not > 0.1 m
        assert (r.depths[4] == 0.0).sum() == 4 and not np.isfinite(r.corners_px[4][r.depths[4] == 0.0]).any()


def test_a_resized_camera_keeps_the_full_image_edges_in_u_and_v_apart():
    """A camera resized by (0.25, 0.5): the devkit's `box_in_image` limits 0 < u < 1600 and 0 < v < 900 hold on
    the full-size image, so in resized pixels the left edge is at (0.25 - 1) / 2 = -0.375 and the top edge at
    (0.5 - 1) / 2 = -0.25: each edge is its own axis's. Point-like boxes 10 m ahead at full-image pixels a quarter
    pixel inside and outside each edge (the pixels placed by hand through the unresized K)."""
    camera_mount = rigid_transforms([0.0, 0.0, 0.0], [0.5, -0.5, 0.5, -0.5])  # camera x = -ego y, y = -ego z
    cameras = Cameras.from_poses(np.eye(4)[None], camera_mount[None], K[None], [[1600.0, 900.0]]).resized((0.25, 0.5))
    full_px = [(0.25, 450.0), (-0.25, 450.0), (1599.75, 450.0), (1600.25, 450.0),
               (800.0, 0.25), (800.0, -0.25), (800.0, 899.75), (800.0, 900.25)]
    depth = 10.0
    centres = [[depth, -(u - K[0, 2]) / K[0, 0] * depth, -(v - K[1, 2]) / K[1, 1] * depth] for u, v in full_px]
    half_axes = box_half_axes([[1e-6, 1e-6, 1e-6]], [[1.0, 0.0, 0.0, 0.0]])
    inside = [0.0 < u < 1600.0 and 0.0 < v < 900.0 for u, v in full_px]
    assert inside == [True, False] * 4
    for result in _both(cameras, [0] * len(full_px), centres, half_axes, [0] * len(full_px)):
        # the resized pixels are s * (u + 0.5) - 0.5 of the full ones (a millionth of a metre box: ~1e-4 px)
        expected_px = np.array(full_px) * [0.25, 0.5] + [(0.25 - 1.0) / 2, (0.5 - 1.0) / 2]
        np.testing.assert_allclose(result.corners_px, np.broadcast_to(expected_px[:, None], (8, 8, 2)), atol=1e-3)
        np.testing.assert_array_equal(result.corner_visible, np.repeat(np.array(inside)[:, None], 8, axis=1))
        np.testing.assert_array_equal(result.visible, inside)


def test_index_columns_of_any_integer_like_dtype_or_empty_lists_are_taken_as_rows():
    """`frame_index` and `axes_index` are row numbers whatever their dtype: int32 or uint32 (polars' row
    indices), whole floats, or empty Python lists for no pairs; both implementations give the int64 rows' bits."""
    rng = np.random.default_rng(9)
    cameras = _cameras(rng, 3)
    frame = rng.integers(0, 3, 40)
    half_axes = box_half_axes(rng.uniform(0.5, 5.0, (6, 3)), _unit_quaternions(rng, 6))
    axes_row = rng.integers(0, 6, 40)
    translation = _boxes_near(rng, cameras, frame, 15.0)
    expected = project_pairs(cameras, frame, translation, half_axes, axes_row, kernel="numpy")
    assert expected.visible.any()
    for dtype in (np.int32, np.uint32, np.float64):
        for result in _both(cameras, frame.astype(dtype), translation, half_axes, axes_row.astype(dtype)):
            _assert_same_bits(result, expected)
    for result in _both(cameras, [], [], [], []):
        assert result.corners_px.shape == (0, 8, 2) and result.visible.shape == (0,)


def test_extreme_but_finite_values():
    """Far-away cameras (1e6 m), huge and tiny boxes, a huge focal length, boxes 1e-9 m from a camera: both
    implementations give the same bits (infinities and nans where a division by ~0 gives them)."""
    rng = np.random.default_rng(7)
    cameras = _cameras(rng, 6, far_m=1e6)
    focal = np.array([1e6, 1e6, 1e6, 1.0, 1.0, 1.0])[:, None, None] * [[1.0], [1.0], [0.0]] + [[0.0], [0.0], [1.0]]
    cameras = dataclasses.replace(cameras, image_from_camera=cameras.image_from_camera * focal)
    frame = np.repeat(np.arange(6), 50)
    n = len(frame)
    sizes = np.exp(rng.uniform(np.log(1e-9), np.log(1e5), (n, 3)))
    half_axes = box_half_axes(sizes, _unit_quaternions(rng, n))
    spread = np.exp(rng.uniform(np.log(1e-9), np.log(1e4), (n, 1)))
    translation = _boxes_near(rng, cameras, frame, 0.0) + rng.normal(size=(n, 3)) * spread
    numpy_result, compiled_result = _both(cameras, frame, translation, half_axes, np.arange(n))
    _assert_same_bits(numpy_result, compiled_result)
    assert np.isfinite(numpy_result.corners_camera_m).all()
    assert numpy_result.visible.any() and not numpy_result.visible.all()


def test_the_kernel_is_chosen_by_size_unless_told(monkeypatch):
    calls = []
    real = compiled.pair_kernel
    monkeypatch.setattr(compiled, "pair_kernel", lambda: calls.append(1) or real())
    rng = np.random.default_rng(3)
    cameras = _cameras(rng, 2)
    one = (cameras, [0], [[0.0, 0.0, 0.0]], np.eye(3)[None], [0])
    project_pairs(*one)
    assert calls == []  # a small batch: numpy
    project_pairs(*one, kernel="compiled")
    assert calls == [1]
    monkeypatch.setenv("NUPARQUET_KERNEL", "numpy")
    many = np.zeros(COMPILED_MIN_PAIRS, dtype=np.int64)
    project_pairs(cameras, many, np.zeros((len(many), 3)), np.eye(3)[None], many)
    assert calls == [1]
    monkeypatch.setenv("NUPARQUET_KERNEL", "auto")
    project_pairs(cameras, many, np.zeros((len(many), 3)), np.eye(3)[None], many)
    assert calls == [1, 1]
    # the message lists the choices as a user would type them, and the value refused
    with pytest.raises(ValueError, match=r"^kernel must be one of auto, numpy, compiled, got 'fast'$"):
        project_pairs(*one, kernel="fast")


def test_without_numba_one_warning_then_numpy(monkeypatch):
    def broken():
        raise ImportError("No module named 'numba'")

    monkeypatch.setattr(compiled, "_KERNELS", {})
    monkeypatch.setattr(compiled, "_FAILED", [])
    monkeypatch.setattr(compiled, "_build_pair_kernel", broken)
    rng = np.random.default_rng(4)
    cameras = _cameras(rng, 3)
    frame = rng.integers(0, 3, 50)
    args = (cameras, frame, _boxes_near(rng, cameras, frame, 10.0), box_half_axes(np.ones((50, 3)),
                                                                                  _unit_quaternions(rng, 50)),
            np.arange(50))
    with pytest.warns(compiled.KernelUnavailable, match="No module named 'numba'.*using numpy"):
        fallback = project_pairs(*args, kernel="compiled")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once per process, not per call
        again = project_pairs(*args, kernel="compiled")
    _assert_same_bits(fallback, project_pairs(*args, kernel="numpy"))
    _assert_same_bits(again, fallback)


def test_small_projections_and_the_front_door_never_load_numba():
    code = ("import sys, nuparquet, nuparquet.frames.projection, numpy as np\n"
            "from nuparquet.geometry import Cameras, box_projection\n"
            "c = Cameras.from_poses(np.eye(4)[None], np.eye(4)[None], np.eye(3)[None], [[10.0, 10.0]])\n"
            "box_projection.project_pairs(c, [0], [[0.0, 0.0, 5.0]], np.eye(3)[None], [0])\n"
            "print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_the_kernel_source_is_the_documented_arithmetic():
    """The plain-Python kernel (what numba compiles) run as Python gives the numpy columns' bits too."""
    rng = np.random.default_rng(5)
    cameras = _cameras(rng, 4, scale=0.5)
    frame = rng.integers(0, 4, 60)
    half_axes = box_half_axes(rng.uniform(0.5, 5.0, (10, 3)), _unit_quaternions(rng, 10))
    axes_row = rng.integers(0, 10, 60)
    translation = _boxes_near(rng, cameras, frame, 15.0)
    expected = project_pairs(cameras, frame, translation, half_axes, axes_row, kernel="numpy")
    terms = box_projection.FrameTerms.of(cameras)
    out = box_projection._allocate(len(frame))
    with np.errstate(divide="ignore", invalid="ignore"):
        compiled.project_pairs(frame, axes_row, translation, half_axes, terms.ego_rotation, terms.ego_translation,
                               terms.camera_rotation, terms.camera_translation, terms.global_to_camera,
                               terms.intrinsic, terms.low_px, terms.high_px, *box_projection._fields(out))
    _assert_same_bits(expected, out)


def test_project_boxes_gives_the_same_bits_through_either_kernel(synth_out, monkeypatch):
    """Through `project_boxes` on a converted dataset (keyframes and interpolated sweeps of every camera): the
    compiled kernel and the numpy columns agree bit for bit, so the devkit parity of one (tests/parity) is the
    other's."""
    import polars as pl

    from nuparquet.frames.projection import project_boxes

    frames = pl.scan_parquet(synth_out / "frames" / "*.parquet").filter(pl.col("modality") == "camera").collect()
    annotations = pl.read_parquet(synth_out / "annotations" / "*.parquet")
    samples = pl.read_parquet(synth_out / "tables" / "sample" / "*.parquet")
    results = {}
    for kernel in ("numpy", "compiled"):
        monkeypatch.setenv("NUPARQUET_KERNEL", kernel)
        results[kernel] = project_boxes(frames, annotations, samples, visibility="none")
    ours, theirs = results["numpy"], results["compiled"]
    assert len(ours) > 1000 and ours.interpolated.any() and (~ours.interpolated).any()
    names = [f.name for f in dataclasses.fields(ours) if f.name != "cuboids"]
    for name in ["translation_m", "size_wlh_m", "rotation_wxyz", *names]:  # the cuboids' fields, then the rest
        x, y = getattr(ours, name), getattr(theirs, name)
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True) and np.array_equal(np.signbit(x), np.signbit(y)), name
        else:
            np.testing.assert_array_equal(x, y, err_msg=name)
