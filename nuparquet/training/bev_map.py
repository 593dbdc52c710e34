"""A BEV map mask as bevfusion's `LoadBEVSegmentation` makes it (mit-han-lab/bevfusion,
`mmdet3d/datasets/pipelines/loading.py`), through `Dataset.map(location).map_mask` (the devkit's `get_map_mask`
pixel for pixel): a patch of the `xbound` x `ybound` extent centred on the lidar, rotated by the lidar's yaw in
the global frame, each class the union of its map layers."""

from __future__ import annotations

import numpy as np

from nuparquet.geometry import rotation_matrices

BEV_CLASSES = ("drivable_area", "ped_crossing", "walkway", "stop_line", "carpark_area", "divider")
BOUND_M = (-50.0, 50.0, 0.5)  # its nuScenes configs' xbound and ybound: [min, max, cell] in metres


def class_layers(classes: tuple[str, ...]) -> dict[str, list[str]]:
    """The map layers of each class (its `mappings`)."""
    layers = {}
    for name in classes:
        if name == "drivable_area*":
            layers[name] = ["road_segment", "lane"]
        elif name == "divider":
            layers[name] = ["road_divider", "lane_divider"]
        else:
            layers[name] = [name]
    return layers


def canvas(xbound: tuple[float, float, float], ybound: tuple[float, float, float]) -> tuple[tuple, tuple]:
    """(patch_h, patch_w) [m] and (canvas_h, canvas_w) [px] of the bounds."""
    patch_h, patch_w = ybound[1] - ybound[0], xbound[1] - xbound[0]
    return (patch_h, patch_w), (int(patch_h / ybound[2]), int(patch_w / xbound[2]))


def lidar2global(lidar_t, lidar_q, ego_t, ego_q) -> np.ndarray:
    """(4, 4) float32 `ego2global @ lidar2ego` built as bevfusion's `get_data_info` builds them (float32 matrices of
    the quaternions' rotation matrices and the translations; no augmentation: `lidar_aug_matrix` is the identity)."""
    ego2global = np.eye(4).astype(np.float32)
    ego2global[:3, :3] = rotation_matrices(np.asarray(ego_q))
    ego2global[:3, 3] = ego_t
    lidar2ego = np.eye(4).astype(np.float32)
    lidar2ego[:3, :3] = rotation_matrices(np.asarray(lidar_q))
    lidar2ego[:3, 3] = lidar_t
    point2lidar = np.linalg.inv(np.eye(4).astype(np.float32))
    return ego2global @ lidar2ego @ point2lidar


def bev_mask(map_layers, from_lidar: np.ndarray, classes: tuple[str, ...], patch_size: tuple, canvas_size: tuple
             ) -> np.ndarray:
    """(K, canvas_h, canvas_w) uint8 0/1 of `classes` around the lidar pose `from_lidar` (lidar2global), from
    `map_layers` (a `MapLayers`): `LoadBEVSegmentation.__call__`'s `gt_masks_bev` (which it holds as int64)."""
    map_pose = from_lidar[:2, 3]
    patch_box = (map_pose[0], map_pose[1], patch_size[0], patch_size[1])
    v = np.dot(from_lidar[:3, :3], np.array([1, 0, 0]))
    patch_angle = np.arctan2(v[1], v[0]) / np.pi * 180
    mappings = class_layers(classes)
    layer_names = sorted({layer for name in mappings for layer in mappings[name]})  # its list(set(...)): any order
    masks = map_layers.map_mask(patch_box, patch_angle, layer_names, canvas_size)
    masks = masks.transpose(0, 2, 1).astype(bool)
    labels = np.zeros((len(classes), *canvas_size), dtype=np.uint8)
    for k, name in enumerate(classes):
        for layer in mappings[name]:
            labels[k, masks[layer_names.index(layer)]] = 1
    return labels


def sample_locations(ds, sample_scene: np.ndarray) -> np.ndarray:
    """(S,) the map location of each sample's scene (scene -> log -> location)."""
    import polars as pl

    logs = ds.scan("tables/log").select(pl.col("token").alias("log_token"), "location")
    scenes = ds.scan("tables/scene").select(pl.col("token").alias("scene_token"), "log_token").join(
        logs, on="log_token", how="left").collect()
    location = dict(zip(scenes["scene_token"].to_list(), scenes["location"].to_list()))
    return np.array([location[t] for t in sample_scene.tolist()], dtype=str)
