"""The devkit's `nuscenes.utils.geometry_utils` over (3, N) column arrays: `BoxVisibility`, `view_points`,
`box_in_image`, `transform_matrix`, `points_in_box`.

These are the devkit's own small formulas, kept operation for operation (the same numpy products, in the same
order), so their results are bit-identical to the devkit's; nuparquet's batch forms over (N, 3) rows and stacks
of frames are `nuparquet.geometry` (`view_points`, `count_points_in_boxes`, `rigid_transforms`).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np
from pyquaternion import Quaternion


class BoxVisibility(IntEnum):
    """How much of a box must be in an image (`box_in_image`); equal to the devkit's values (0, 1, 2)."""

    ALL = 0  # every corner in the image
    ANY = 1  # at least one corner in the image
    NONE = 2  # no requirement: the box may be wholly outside


def view_points(points: np.ndarray, view: np.ndarray, normalize: bool) -> np.ndarray:
    """(3, N) points projected by a view matrix of at most 4x4 (padded to 4x4 with the identity): a 3x3 camera
    intrinsic with `normalize=True` gives pixels [u, v, 1]; `normalize=False` keeps the third coordinate."""
    assert view.shape[0] <= 4
    assert view.shape[1] <= 4
    assert points.shape[0] == 3

    viewpad = np.eye(4)
    viewpad[:view.shape[0], :view.shape[1]] = view
    nbr_points = points.shape[1]
    points = np.concatenate((points, np.ones((1, nbr_points))))  # homogeneous
    points = np.dot(viewpad, points)[:3, :]
    if normalize:
        points = points / points[2:3, :].repeat(3, 0).reshape(3, nbr_points)
    return points


def box_in_image(box, intrinsic: np.ndarray, imsize: tuple[int, int], vis_level: int = BoxVisibility.ANY) -> bool:
    """Is `box` (in the camera frame) visible in an image of `imsize` (width, height), ignoring occlusion?

    A corner is visible when its pixel lies strictly inside the image and it is more than 1 m deep; every corner
    must be more than 0.1 m in front of the camera. ALL needs every corner visible, ANY one, NONE none."""
    corners_3d = box.corners()
    corners_img = view_points(corners_3d, intrinsic, normalize=True)[:2, :]

    visible = np.logical_and(corners_img[0, :] > 0, corners_img[0, :] < imsize[0])
    visible = np.logical_and(visible, corners_img[1, :] < imsize[1])
    visible = np.logical_and(visible, corners_img[1, :] > 0)
    visible = np.logical_and(visible, corners_3d[2, :] > 1)
    in_front = corners_3d[2, :] > 0.1

    if vis_level == BoxVisibility.ALL:
        return all(visible) and all(in_front)
    if vis_level == BoxVisibility.ANY:
        return any(visible) and all(in_front)
    if vis_level == BoxVisibility.NONE:
        return True
    raise ValueError("vis_level: {} not valid".format(vis_level))


def transform_matrix(translation: np.ndarray = np.array([0, 0, 0]),
                     rotation: Quaternion = Quaternion([1, 0, 0, 0]),
                     inverse: bool = False) -> np.ndarray:
    """(4, 4) float64 X_from_Y from the pose of Y in X (`inverse=True`: Y_from_X), as the devkit builds it."""
    tm = np.eye(4)
    if inverse:
        rot_inv = rotation.rotation_matrix.T
        trans = np.transpose(-np.array(translation))
        tm[:3, :3] = rot_inv
        tm[:3, 3] = rot_inv.dot(trans)
    else:
        tm[:3, :3] = rotation.rotation_matrix
        tm[:3, 3] = np.transpose(np.array(translation))
    return tm


def points_in_box(box, points: np.ndarray, wlh_factor: float = 1.0) -> np.ndarray:
    """(N,) bool: which of the (3, N) `points` lie in `box` (faces included), the box scaled by `wlh_factor`.

    Offsets from corner 0 are projected on the edges to corners 4 (length), 1 (width) and 3 (height)."""
    corners = box.corners(wlh_factor=wlh_factor)
    p1 = corners[:, 0]
    i = corners[:, 4] - p1
    j = corners[:, 1] - p1
    k = corners[:, 3] - p1
    v = points - p1.reshape((-1, 1))
    iv, jv, kv = np.dot(i, v), np.dot(j, v), np.dot(k, v)
    mask_x = np.logical_and(0 <= iv, iv <= np.dot(i, i))
    mask_y = np.logical_and(0 <= jv, jv <= np.dot(j, j))
    mask_z = np.logical_and(0 <= kv, kv <= np.dot(k, k))
    return np.logical_and(np.logical_and(mask_x, mask_y), mask_z)
