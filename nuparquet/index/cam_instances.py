"""`cam_instances` of the v2 infos (mmdetection3d `get_nuscenes_2d_boxes`) for every (sample, camera, box) at
once: boxes into each camera's frame, the convex hull of the corners in front of the camera projected and
clipped to the image canvas (shapely's vectorised GEOS calls, as the converter uses shapely), the 3D box and
velocity in the camera frame, the projected centre and its depth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from nuparquet.errors import InputError
from nuparquet.index.replay import blas, quaternions, transforms
from nuparquet.index.labels import ATTRIBUTES, label_of

VISIBILITIES = ("", "1", "2", "3", "4")  # the converter's filter (every nuScenes visibility)
CANVAS_PX = (1600, 900)  # the converter's fixed image size (post_process_coords' default)


@dataclass
class CamInstances:
    sample: np.ndarray  # (K,) sample row, records sorted by sample, camera, annotation
    ann: np.ndarray  # (K,) annotation row (Inputs.ann_*)
    camera: np.ndarray  # (K,) camera index
    label: np.ndarray  # (K,) int
    bbox: np.ndarray  # (K, 4) x1, y1, x2, y2
    bbox_3d: np.ndarray  # (K, 7) x, y, z, l, h, w, -yaw in the camera frame
    velocity: np.ndarray  # (K, 2) vx, vz in the camera frame
    center_2d: np.ndarray  # (K, 2) float32 arithmetic, like mmdet3d's points_cam2img (float64 with `legacy`)
    depth: np.ndarray  # (K,)
    attr_label: np.ndarray  # (K,) int


def _hull_bounds(corners_uv: np.ndarray, in_front: np.ndarray, canvas=CANVAS_PX) -> tuple[np.ndarray, np.ndarray]:
    """(ok (N,), bounds (N, 4)): bounds of convex_hull(corners in front) ∩ canvas when that is a polygon."""
    n = len(corners_uv)
    ok = np.zeros(n, bool)
    bounds = np.full((n, 4), np.nan)
    owner, corner = np.nonzero(in_front)
    if len(owner) == 0:
        return ok, bounds
    has = np.unique(owner)
    points = shapely.multipoints(corners_uv[owner, corner], indices=np.searchsorted(has, owner))
    hull = shapely.convex_hull(points)
    canvas_box = shapely.box(0, 0, canvas[0], canvas[1])
    hits = shapely.intersects(hull, canvas_box)
    clipped = shapely.intersection(hull[hits], canvas_box)
    polygon = shapely.get_type_id(clipped) == shapely.GeometryType.POLYGON
    rows = has[hits][polygon]
    ok[rows] = True
    bounds[rows] = shapely.bounds(clipped[polygon])
    return ok, bounds


def _rough_may_meet_canvas(center, size_wlh, orientation, k, canvas=CANVAS_PX) -> np.ndarray:
    """(N,) bool: False only where the box surely has no record: its centre behind the camera (depth <= 0)
    or no corner in front of it, or the bounding rectangle of the projected corners clear of the canvas.
    From `transforms.rough_boxes_to_sensor` values and plain float products, with wide margins; the exact
    arithmetic then runs on the rest only (a box meets ~1 of the 6 images)."""
    r = quaternions.rough_rotation_matrices(orientation)
    corners = np.einsum("nij,njk->nik", r, transforms.box_local_corners(size_wlh)) + center[:, :, None]
    projected = np.einsum("nij,njk->nik", k, corners)
    depth = np.einsum("nj,nj->n", k[:, 2], center)  # the exact one is float32 arithmetic: margin below
    maybe_front = corners[:, 2] > -1e-6
    near_zero = (maybe_front & (corners[:, 2] < 1e-6)).any(axis=1)  # projections unbounded: keep
    with np.errstate(divide="ignore", invalid="ignore"):  # inf - inf where no corner is in front: not kept anyway
        uv = projected[:, :2] / projected[:, 2:3]
        lo = np.where(maybe_front[:, None], uv, np.inf).min(axis=2)
        hi = np.where(maybe_front[:, None], uv, -np.inf).max(axis=2)
        margin = 1e-3 + 1e-9 * np.maximum(np.abs(lo), np.abs(hi))
        clear = ((hi + margin < 0) | (lo - margin > np.array(canvas))).any(axis=1)
    depth_margin = 1e-3 + 1e-6 * np.einsum("nj,nj->n", np.abs(k[:, 2]), np.abs(center))
    return (depth > -depth_margin) & maybe_front.any(axis=1) & (near_zero | ~clear)


def _boxes_2d(center, size_wlh, orientation, k, canvas=CANVAS_PX) -> tuple[np.ndarray, np.ndarray]:
    """(ok (N,), bounds (N, 4)): `post_process_coords` of each box's projected corners, exact. A hull wholly
    inside the canvas (8 corners in front, all strictly inside) is its own intersection with it: its bounds
    are the corners' extremes, without GEOS."""
    n = len(center)
    ok = np.zeros(n, bool)
    bounds = np.full((n, 4), np.nan)
    corners = transforms.box_corners(center, size_wlh, orientation)  # (N, 3, 8)
    # view_points: np.dot(viewpad, [corners; 1]), the 4th term (0 * 1) changes nothing
    projected = blas.gemm(k, corners)
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.moveaxis(projected[:, :2] / projected[:, 2:3], 1, 2)  # (N, 8, 2)
    in_front = corners[:, 2] > 0
    inside = in_front.all(axis=1) & (size_wlh > 0).all(axis=1) & (uv > 0).all(axis=(1, 2)) \
        & (uv < np.array(canvas)).all(axis=(1, 2))
    ok[inside] = True
    bounds[inside] = np.concatenate([uv[inside].min(axis=1), uv[inside].max(axis=1)], axis=1)
    ok[~inside], bounds[~inside] = _hull_bounds(uv[~inside], in_front[~inside], canvas)
    return ok, bounds


BLOCK_BOXES = 200_000  # box-camera pairs per vectorised pass: bounds the temporaries (~0.5 GB) at trainval


def _center_image_f64(center: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(N, 3) mmdetection3d 0.17's `box_np_ops.points_cam2img` before its division, in float64 numpy:
    `[x, y, z, 1] @ P.T` with P the 3x3 intrinsic `k` (N, 3, 3) padded into eye(4), which numpy hands to
    BLAS as a dgemv_t (4 terms summed (p0 + p2) + (p1 + p3): `blas.gemv_rows`)."""
    p = np.zeros(k.shape[:-2] + (4, 4))
    p[..., :3, :3] = k
    p[..., 3, 3] = 1.0
    return blas.gemv_rows(p, np.concatenate([center, np.ones(center.shape[:-1] + (1,))], axis=-1))[..., :3]


def _camera_block(inputs, c: int, a: np.ndarray, r: np.ndarray, labels_all: np.ndarray, legacy: bool = False) -> dict:
    """The camera instances of annotations `a` (rows) seen by camera `c` through its readings `r`."""
    d = inputs.data
    rough = transforms.rough_boxes_to_sensor(inputs.ann_center[a], inputs.ann_rotation[a], r, d.ego_t, d.ego_q,
                                             d.sensor_t, d.sensor_q)
    maybe = _rough_may_meet_canvas(*rough[:1], inputs.ann_size_wlh[a], rough[1], d.intrinsic[r])
    a, r = a[maybe], r[maybe]
    center, orientation = transforms.boxes_to_sensor(inputs.ann_center[a], inputs.ann_rotation[a], r, d.ego_t,
                                                     d.ego_q, d.sensor_t, d.sensor_q)
    k = d.intrinsic[r]
    if legacy:
        image = _center_image_f64(center, k)
    else:
        center32, k32 = center.astype(np.float32), k.astype(np.float32)
        image = (k32[:, :, 0] * center32[:, None, 0] + k32[:, :, 1] * center32[:, None, 1]) \
            + k32[:, :, 2] * center32[:, None, 2]
    depth = image[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        center_2d = image[:, :2] / depth[:, None]
    front = depth > 0  # the converter's last filter, applied first: the filters commute
    a, r, center, orientation, k = a[front], r[front], center[front], orientation[front], k[front]
    depth, center_2d = depth[front], center_2d[front]
    ok, bounds = _boxes_2d(center, inputs.ann_size_wlh[a], orientation, k)
    a, r = a[ok], r[ok]
    wlh = inputs.ann_size_wlh[a]
    velocity = transforms.velocity_to_sensor(inputs.ann_velocity[a, :2], r, d.ego_q, d.sensor_q)
    return dict(
        ann=a, camera=np.full(len(a), c), label=labels_all[a], bbox=bounds[ok],
        bbox_3d=np.column_stack([center[ok], wlh[:, 1], wlh[:, 2], wlh[:, 0], -quaternions.yaw(orientation[ok])]),
        velocity=velocity[:, [0, 2]], center_2d=center_2d[ok].astype(np.float64),
        depth=depth[ok].astype(np.float64), attr_label=np.searchsorted(ATTRIBUTES_SORTED, inputs.ann_attribute[a]))


def camera_instances(inputs, cameras: tuple[str, ...], *, legacy: bool = False) -> CamInstances:
    """Every (sample, camera, box) record of mmdetection3d v1.4.0's `get_nuscenes_2d_boxes`; `legacy`: of
    0.17's `get_2d_boxes` (the same records and numbers, but its centre and depth are float64 numpy, and its
    depth filter runs on them)."""
    labels_all = label_of(inputs.ann_category)
    # generate_record drops classes outside the ten: never a record, so never computed
    keep_ann = np.flatnonzero(np.isin(inputs.ann_visibility, VISIBILITIES) & (labels_all >= 0))
    parts = []
    for c, channel in enumerate(cameras):  # vectorised passes per camera (6) and block of boxes, never per box
        cam_row = inputs.keyframe[channel][inputs.ann_sample[keep_ann]]
        for block in range(0, max(len(keep_ann), 1), BLOCK_BOXES):  # one (maybe empty) block at least
            rows = cam_row[block:block + BLOCK_BOXES]
            parts.append(_camera_block(inputs, c, keep_ann[block:block + BLOCK_BOXES][rows >= 0], rows[rows >= 0],
                                       labels_all, legacy))
    merged = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    unknown = ~np.isin(inputs.ann_attribute[merged["ann"]], ATTRIBUTES)
    if unknown.any():  # the converter's nus_attributes.index(attr_name) raises there
        row = merged["ann"][np.argmax(unknown)]
        raise InputError(f"sample_annotation {inputs.ann_token[row]} has the attribute "
                         f"{inputs.ann_attribute[row]!r}, which mmdetection3d's nuScenes attributes lack "
                         f"({', '.join(ATTRIBUTES)}): its converter stops there")
    sample = inputs.ann_sample[merged["ann"]]
    order = np.lexsort((merged["ann"], merged["camera"], sample))
    attr = ATTRIBUTE_ORDER[merged["attr_label"][order]]
    return CamInstances(sample=sample[order], ann=merged["ann"][order], camera=merged["camera"][order],
                        label=merged["label"][order],
                        bbox=merged["bbox"][order], bbox_3d=merged["bbox_3d"][order],
                        velocity=merged["velocity"][order], center_2d=merged["center_2d"][order],
                        depth=merged["depth"][order], attr_label=attr)


ATTRIBUTES_SORTED = np.array(sorted(ATTRIBUTES))
ATTRIBUTE_ORDER = np.array([ATTRIBUTES.index(a) for a in ATTRIBUTES_SORTED])
