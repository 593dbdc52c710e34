"""Lane centrelines from arcline paths, pose for pose as the devkit's `arcline_path_utils.discretize_lane`.

Vectorised over every path of a map at once (numpy), with the devkit's exact arithmetic order, including its
quirk that the segment index advances by at most one per step (`discretize`'s `g_i`), so a zero-length middle
segment is taken one step late exactly as the devkit takes it.
"""

from __future__ import annotations

import numpy as np

_SIGNS = {  # compute_segment_sign: 1 left, -1 right, 0 straight, per shape
    "LRL": (1, -1, 1), "LSL": (1, 0, 1), "LSR": (1, 0, -1), "RLR": (-1, 1, -1), "RSL": (-1, 0, 1), "RSR": (-1, 0, -1),
}
TWO_PI = 2 * np.pi


def _signs(shapes: list[str]) -> np.ndarray:
    """(P, 3) segment signs; an unknown shape gets the devkit's fall-through values (-1, 0, -1)."""
    return np.array([_SIGNS.get(s, (-1, 0, -1)) for s in shapes], dtype=np.float64).reshape(-1, 3)


def _principal(angle: np.ndarray) -> np.ndarray:
    return (angle - (-np.pi)) % TWO_PI + (-np.pi)


def _step(curvature: np.ndarray, step: np.ndarray, pose_x=1.0, pose_y=0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """get_transformation_at_step for poses (pose_x, pose_y, curvature): an arcline path's Lie algebra poses are
    (1.0, 0.0, curvature)."""
    theta = curvature * step
    c, s = np.cos(theta), np.sin(theta)
    straight = np.abs(curvature) < 1e-6
    safe = np.where(straight, 1.0, curvature)
    x = np.where(straight, pose_x * step, (pose_y * (c - 1.0) + pose_x * s) / safe)
    y = np.where(straight, pose_y * step, (pose_x * (1.0 - c) + pose_y * s) / safe)
    return x, y, theta


def _apply(px, py, pyaw, tx, ty, tyaw):
    """apply_affine_transformation."""
    c, s = np.cos(pyaw), np.sin(pyaw)
    return c * tx - s * ty + px, s * tx + c * ty + py, _principal(pyaw + tyaw)


def _pose_at_length(start: np.ndarray, curv: np.ndarray, lengths: np.ndarray, pos: np.ndarray):
    """pose_at_length for many (path, pos): start (N, 3), curv (N, 3), lengths (N, 3), pos (N,)."""
    pos = np.maximum(0.0, np.minimum(pos, _total(lengths)))
    x, y, yaw = start[:, 0].copy(), start[:, 1].copy(), start[:, 2].copy()
    done = np.zeros(len(pos), dtype=bool)
    for i in range(3):
        partial = ~done & (pos <= lengths[:, i])
        step = np.where(partial, pos, lengths[:, i])
        tx, ty, tyaw = _step(curv[:, i], step)
        nx, ny, nyaw = _apply(x, y, yaw, tx, ty, tyaw)
        x, y, yaw = np.where(done, x, nx), np.where(done, y, ny), np.where(done, yaw, nyaw)
        pos = np.where(done | partial, pos, pos - lengths[:, i])
        done |= partial
    return x, y, yaw


def _total(lengths: np.ndarray) -> np.ndarray:
    """sum(segment_length) in Python's left-to-right order."""
    return (lengths[:, 0] + lengths[:, 1]) + lengths[:, 2]


def discretize_paths(start_pose: np.ndarray, shapes: list[str], radius: np.ndarray, segment_length: np.ndarray,
                     resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Poses of P arcline paths: start_pose (P, 3), shapes (P,), radius (P,), segment_length (P, 3) ->
    (N, 3) poses [x, y, yaw] and (P,) pose counts (path p's poses follow path p-1's)."""
    p = len(radius)
    if p == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    length = _total(segment_length)
    n = np.maximum(np.ceil(length / resolution_m) + 1.5, 2).astype(np.int64)
    res = length / (n - 1)
    cum = np.stack([segment_length[:, 0], segment_length[:, 0] + segment_length[:, 1], length + res], axis=1)
    with np.errstate(divide="ignore"):
        curv = _signs(shapes) / radius[:, None]
    path = np.repeat(np.arange(p), n)
    first = np.r_[0, np.cumsum(n)[:-1]]
    k = np.arange(n.sum()) - np.repeat(first, n)
    along = k * res[path]
    # the devkit's segment index: +1 at the first step past cum[0], +1 again at the next step past cum[1]
    big = np.iinfo(np.int64).max
    k1 = np.minimum.reduceat(np.where(along > cum[path, 0], k, big), first)
    past1 = (along > cum[path, 1]) & (k > k1[path])
    k2 = np.minimum.reduceat(np.where(past1, k, big), first)
    seg = (k >= k1[path]).astype(np.int64) + (k >= k2[path])
    # the pose the current segment starts from: the start pose, or pose_at_length at the step it advanced
    base = np.zeros((p, 3, 3))
    base[:, 0] = start_pose
    for j, kj in ((1, k1), (2, k2)):
        has = kj < big
        pos = np.where(has, np.minimum(kj, n - 1) * res, 0.0)
        base[:, j] = np.stack(_pose_at_length(start_pose, curv, segment_length, pos), axis=1)
        base[~has, j] = np.nan
    g_s = np.stack([np.zeros(p), np.where(k1 < big, k1 * res, 0.0), np.where(k2 < big, k2 * res, 0.0)], axis=1)
    b = base[path, seg]
    tx, ty, tyaw = _step(curv[path, seg], along - g_s[path, seg])
    x, y, yaw = _apply(b[:, 0], b[:, 1], b[:, 2], tx, ty, tyaw)
    return np.stack([x, y, yaw], axis=1), n


def discretize_lanes(paths_per_lane: list[list[dict]], resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Every lane's poses (devkit `discretize_lane` per lane): (N, 3) poses and (L,) pose counts per lane."""
    paths = [path for lane in paths_per_lane for path in lane]
    per_lane = np.array([len(lane) for lane in paths_per_lane], dtype=np.int64)
    if not paths:
        return np.zeros((0, 3)), np.zeros(len(paths_per_lane), np.int64)
    poses, counts = discretize_paths(
        np.array([p["start_pose"] for p in paths], dtype=np.float64).reshape(-1, 3), [p["shape"] for p in paths],
        np.array([p["radius"] for p in paths], dtype=np.float64),
        np.array([p["segment_length"] for p in paths], dtype=np.float64).reshape(-1, 3), resolution_m)
    lane_of_path = np.repeat(np.arange(len(paths_per_lane)), per_lane)
    return poses, np.bincount(lane_of_path, weights=counts, minlength=len(paths_per_lane)).astype(np.int64)
