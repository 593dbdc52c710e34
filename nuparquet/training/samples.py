"""`Samples`: one split of a converted dataset as a map-style training dataset with mmdetection3d v1.4.0's
semantics, built from the same arrays as the v2 infos (`nuparquet.index`), so every matrix and box is the infos'.

Order: the split's samples in scene-table order, then by timestamp within a scene (stable across runs).

At construction the index's `compute` and `v2_arrays` run once for the split and only small per-sample arrays are
kept (tokens, file names, 4x4 matrices, boxes); tables are not held; a spawned worker reopens the dataset from its
picklable reference. Forked workers serve the default parts (no polars computation per item); the radar, devkit-sweep
and BEV-map parts need spawned workers (`shards.check_worker`). Sensors are read through `ds.sensors`, per item.
"""

from __future__ import annotations

import numpy as np

from nuparquet.dataset import Dataset, as_dataset
from nuparquet.errors import UsageError
from nuparquet.index.bevformer import CAN_BUS_DATASET, can_bus_vectors
from nuparquet.index.compute import compute, offsets
from nuparquet.index.inputs import read_inputs
from nuparquet.index.labels import CLASSES
from nuparquet.index.options import DEFAULT_CAMERAS, DEFAULT_LIDAR
from nuparquet.index.splits import assign_splits, converter_version, split_names
from nuparquet.index.v2_arrays import gather_segments, v2_arrays
from nuparquet.sensors.reader import XYZI
from nuparquet.training.bev_map import BEV_CLASSES, BOUND_M, bev_mask, canvas, lidar2global, sample_locations
from nuparquet.training.devkit_sweeps import devkit_points, radar_points
from nuparquet.training.mmdet3d import camera_matrices, gt_bboxes_3d, remove_close
from nuparquet.training.shards import check_worker
from nuparquet.training.temporal import patched_can_bus, queue_rows, union2one

BOX_FILTERS = ("valid_flag", "num_lidar_pts", None)
SWEEPS_AS = ("mmdet3d", "devkit")


class Samples:
    """The samples of `split` ("train", "val", "test") of `dataset` (a `Dataset` or an output path).

    `samples[i]` is a dict (only the parts asked for):

    - `sample_token` (str), `timestamp_us` (int), `scene_token` (str)
    - `points` (P, 5) float32 x, y, z [m] in the keyframe LIDAR_TOP frame, intensity (as in the file), time lag
      [s] (`sample ts - sweep ts`, 0 for the keyframe): the keyframe and up to `sweeps` previous lidar sweeps
      aggregated as mmdetection3d v1.4.0's `LoadPointsFromFile(load_dim=5)` + `LoadPointsFromMultiSweeps(
      sweeps_num=sweeps, remove_close=True, pad_empty_sweeps=True, test_mode=True)` do from the v2 infos (each
      sweep's `lidar2sensor` applied as that class applies it; the infos hold at most `sweeps` sweeps, so every
      one is used); `lidar_sweeps` (int): how many sweeps were found
    - `gt_bboxes_3d` (N, 7) float32 bottom centre x, y, z [m], l, w, h [m], yaw [rad] in the lidar frame
      (mmdetection3d's `LiDARInstance3DBoxes` of the infos' `instances[].bbox_3d`), (N, 9) with `velocity`:
      vx, vy [m/s] in the lidar frame appended, NaN set to 0; `gt_labels_3d` (N,) int64 index into `classes`, -1
      for other classes; `num_lidar_pts` (N,) int64; boxes kept by `box_filter`: "valid_flag" (the infos'
      `bbox_3d_isvalid`: lidar + radar points > 0, mmdetection3d's `use_valid_flag=True`), "num_lidar_pts"
      (> 0, its default) or None (all)
    - `img` (C, H, W, 3) uint8 decoded by cv2: BGR, as mmdetection3d's `LoadMultiViewImageFromFiles` (mmcv's
      `imfrombytes`, cv2 backend) gives them; `rgb=True`: RGB (the channel order of BEVFusion's loader, which
      decodes with pillow); a list when the sizes differ. Camera matrices as mmdetection3d's BEVFusion project
      (`BEVLoadMultiViewImageFromFiles`) builds them from the infos, operation for operation: `cam2img` (C, 4, 4)
      float32 (the 3x3 intrinsic padded), `lidar2cam` (C, 4, 4) float64 (the infos'), `cam2lidar` (C, 4, 4)
      float64 (its inverse from the float32 rotation and translation), `lidar2img` (C, 4, 4) float32 = cam2img @
      lidar2cam in float32; cameras in `cameras` order (the infos' order)

    Optional parts (off by default):

    - `sweeps_as="devkit"`: `points` (P, 5) float32 as the devkit's `LidarPointCloud.from_file_multisweep(nusc,
      sample, lidar_channel, lidar_channel, nsweeps=sweeps + 1, min_distance=close_radius_m)` gives them (every
      cloud, the keyframe's too, without its close points; x, y, z [m] in the keyframe lidar frame, intensity,
      and its `times` [s] as the fifth column); `lidar_sweeps`: how many previous sweeps it found
    - `radars` (channel names or "all": the rig's, sorted): `radar_points` (R, 19) float32 for nuScenes radars
      (the PCD's 18 fields, then the time lag [s]), each radar as the devkit's `RadarPointCloud.
      from_file_multisweep(nusc, sample, radar, lidar_channel, nsweeps=radar_sweeps + 1, min_distance=
      close_radius_m)` gives it (x, y, z [m] in the keyframe lidar frame; vx, vy, vx_comp, vy_comp [m/s] left in
      the radar's frame, as the devkit leaves them; its default filters unless `radar_filters=False`), in
      `radars` order, concatenated
    - `can_bus=True`: `can_bus` (18,) float64, BEVFormer's vector as its `CustomNuScenesDataset.get_data_info`
      hands it to the pipeline: the converter's `_get_can_bus_info` (the `sample_can_bus` dataset), then x, y, z
      [m] of the lidar keyframe's ego pose (global frame), its rotation's w in values 3..6 (BEVFormer's quirk:
      `temporal.patched_can_bus`), and its yaw [rad] and [deg] in [0, 360) as the last two; zeros 7..15 for a scene
      without CAN bus
    - `bev_map=True`: `gt_masks_bev` (K, H, W) uint8 0/1 of `bev_classes` (bevfusion's six by default; "divider":
      road and lane dividers, "drivable_area*": road segments and lanes), a `bev_xbound` x `bev_ybound` patch
      ([min, max, cell] m, default +-50 m at 0.5 m) centred on the lidar and turned with its yaw, indexed [class,
      x cell, y cell] of that frame (its transpose of the map mask), as bevfusion's
      `LoadBEVSegmentation` makes it through `Dataset.map(location).map_mask` (the map held per worker, once per
      location)
    - `queue_length=Q` > 1: BEVFormer's temporal queue: the sample's own fields plus `queue` (the Q - 1 previous
      rows' fields, oldest first: rows i - Q + 1 .. i - 1 of the split's order, clamped at 0, so at a scene start
      the queue reaches into the previous scene as BEVFormer's does), `queue_index` (Q,) int64 those rows then i,
      and in every frame `prev_bev_exists` (False where the scene differs from the previous frame's, and in the
      first) with `can_bus` position and angle made relative to the previous frame as its `union2one` does
    """

    def __init__(self, dataset: str | Dataset, split: str = "train", *, lidar: bool = True, sweeps: int = 10,
                 cameras: tuple[str, ...] | None = DEFAULT_CAMERAS, boxes: bool = True,
                 classes: tuple[str, ...] = CLASSES, velocity: bool = True, box_filter: str | None = "valid_flag",
                 close_radius_m: float = 1.0, pad_empty_sweeps: bool = True, version: str | None = None,
                 lidar_channel: str = DEFAULT_LIDAR, rgb: bool = False, sweeps_as: str = "mmdet3d",
                 radars: tuple[str, ...] | str = (), radar_sweeps: int = 0, radar_filters: bool = True,
                 can_bus: bool = False, bev_map: bool = False, bev_classes: tuple[str, ...] = BEV_CLASSES,
                 bev_xbound: tuple[float, float, float] = BOUND_M, bev_ybound: tuple[float, float, float] = BOUND_M,
                 queue_length: int = 1) -> None:
        for name, value, allowed in (("box_filter", box_filter, BOX_FILTERS), ("sweeps_as", sweeps_as, SWEEPS_AS)):
            if value not in allowed:
                raise UsageError(f"{name} must be one of {allowed}, not {value!r}")
        if queue_length < 1 or radar_sweeps < 0 or sweeps < 0:
            raise UsageError(f"queue_length must be at least 1 and sweeps, radar_sweeps at least 0 (got "
                             f"{queue_length}, {sweeps}, {radar_sweeps})")
        ds = as_dataset(dataset)
        version = converter_version(ds.version, version)
        if split not in split_names(version):
            raise UsageError(f"{version} has no {split} split (it has {', '.join(split_names(version))})")
        self.split, self.lidar, self.sweeps, self.boxes = split, lidar, sweeps, boxes
        self.cameras = tuple(cameras or ())
        self.classes, self.velocity, self.box_filter = tuple(classes), velocity, box_filter
        self.close_radius_m, self.pad_empty_sweeps, self.rgb = close_radius_m, pad_empty_sweeps, rgb
        self.sweeps_as, self.lidar_channel, self.queue_length = sweeps_as, lidar_channel, queue_length
        self.radars = tuple(ds.channels["radars"]) if radars == "all" else tuple(radars)
        if unknown := [r for r in self.radars if r not in ds.channels["radars"]]:
            raise UsageError(f"{', '.join(unknown)}: not a radar of {ds.root} (it has "
                             f"{', '.join(ds.channels['radars']) or 'none'})")
        self.radar_sweeps, self.radar_filters = radar_sweeps, radar_filters
        if can_bus and CAN_BUS_DATASET not in ds.datasets:
            raise UsageError(f"{ds.root} has no {CAN_BUS_DATASET} dataset, which can_bus=True reads: convert the "
                             "dataset again with its CAN bus expansion (DATAROOT/can_bus)")
        self.bev_classes = tuple(bev_classes) if bev_map else ()
        self.bev_patch_m, self.bev_canvas = canvas(bev_xbound, bev_ybound)
        self._reference = ds.reference
        self._ds: Dataset | None = ds

        # the index needs at least one camera; without images its first one is computed and dropped
        index_cameras = self.cameras or tuple(ds.channels["cameras"][:1])
        inputs = read_inputs(ds, index_cameras, lidar_channel)
        computed = compute(inputs, index_cameras, lidar_channel, sweeps, with_annotations=version != "v1.0-test",
                           with_cam_instances=False)
        assigned = assign_splits(version, inputs.scene_token, inputs.scene_name, inputs.sample_scene)
        scene_index = {token: i for i, token in enumerate(inputs.scene_token.tolist())}
        scene_of = np.array([scene_index[t] for t in inputs.sample_scene.tolist()], dtype=np.int64)
        picked = np.flatnonzero(assigned == split)
        picked = picked[np.lexsort((inputs.sample_timestamp_us[picked], scene_of[picked]))]
        arrays = v2_arrays(computed, picked, index_cameras, "")
        d = inputs.data

        # Only fixed-width numpy arrays (no Python objects): a forked worker touches no reference counts, so the
        # pages stay shared, and the pickle is the arrays' bytes.
        self.sample_token = _text(arrays.token)  # (S,) str
        self.timestamp_us = inputs.sample_timestamp_us[picked]  # (S,) int64
        self.scene_token = _text(inputs.sample_scene[picked])  # (S,) str
        self.scene = scene_of[picked]  # (S,) scene-table row of each sample, non-decreasing
        self._lidar_token = _bytes(d.token[computed.lidar_row[picked]])  # (S,)
        self._lidar_file = _bytes(d.filename[computed.lidar_row[picked]])  # (S,)
        self._sweep_offsets = arrays.sweep_offsets  # (S + 1,)
        self._sweep_token = _bytes(arrays.sweep_token)  # (W,)
        self._sweep_file = _bytes(d.filename[computed.sweep_row[_sweep_items(computed, picked)]])  # (W,)
        self._sweep_timestamp_s = arrays.sweep_timestamp_s  # (W,) float64, the infos' `timestamp`
        self._sweep_lidar2sensor = arrays.sweep_lidar2sensor  # (W, 4, 4) float32, the infos' `lidar2sensor`
        n_cam = len(self.cameras)
        self._cam_token = _bytes(arrays.cam_token[:, :n_cam])  # (S, C)
        self._cam_file = _bytes(d.filename[computed.cam_row[picked][:, :n_cam]])  # (S, C)
        self._cam2img = arrays.cam2img[:, :n_cam].astype(np.float32)  # (S, C, 3, 3): read as float32 only
        self._lidar2cam = arrays.lidar2cam[:, :n_cam]  # (S, C, 4, 4) float32, the infos' `lidar2cam`
        self._ann_offsets = arrays.ann_offsets  # (S + 1,)
        class_index = {name: i for i, name in enumerate(self.classes)}
        self._ann_label = np.array([class_index.get(n, -1) for n in arrays.ann_name.tolist()], dtype=np.int32)
        self._ann_box = gt_bboxes_3d(arrays.ann_box, arrays.ann_velocity)  # (A, 9) float32
        self._ann_valid = arrays.ann_valid  # (A,) bool
        self._ann_num_lidar_pts = arrays.ann_num_lidar_pts.astype(np.int32)  # (A,)
        lidar_rows = computed.lidar_row[picked]
        self._lidar_t, self._lidar_q = d.sensor_t[lidar_rows], d.sensor_q[lidar_rows]  # keyframe lidar (CAN, map)
        self._ego_t, self._ego_q = d.ego_t[lidar_rows], d.ego_q[lidar_rows]  # (S, 3), (S, 4)
        self._can_bus = (patched_can_bus(can_bus_vectors(ds, inputs.sample_token[picked]), self._ego_t, self._ego_q)
                         if can_bus else None)  # (S, 18) float64
        self._location = _bytes(sample_locations(ds, inputs.sample_scene[picked])) if bev_map else None  # (S,)
        self.indices = np.arange(len(picked))  # the rows this object serves (a shard serves fewer)

    # -- pickling: small, and the dataset reopened where it is used ----------------------------------------------

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_ds"] = None
        return state

    @property
    def dataset(self) -> Dataset:
        """The opened dataset (opened again from its reference after unpickling)."""
        if self._ds is None:
            self._ds = self._reference.open()
        return self._ds

    # -- shards and the stream ----------------------------------------------------------------------------------

    def shard(self, rank: int, world_size: int) -> Samples:
        """The samples of rank `rank` of `world_size`: whole scenes, every scene on exactly one rank, balanced by
        sample count (`shards.scene_parts`); empty when there are more ranks than scenes."""
        from nuparquet.training.shards import shard

        return shard(self, rank, world_size)

    def stream(self, *, seed: int = 0, shuffle: bool = True, sequential: bool = False):
        """These samples as a seeded, resumable iterable (`shards.SampleStream`)."""
        from nuparquet.training.shards import SampleStream

        return SampleStream(self, seed=seed, shuffle=shuffle, sequential=sequential)

    # -- the map-style dataset -------------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, i: int) -> dict:
        if not -len(self.indices) <= i < len(self.indices):
            raise IndexError(f"sample {i} of {len(self.indices)}")
        s = int(self.indices[i])
        check_worker(self)
        if self.queue_length == 1:
            return self._frame(s)
        # BEVFormer's queue: the frames before this one (rows of the whole split, whatever the shard), then union2one
        rows = queue_rows(s, self.queue_length)
        frames = [self._frame(r) for r in rows]
        exists, can_bus = union2one([f["scene_token"] for f in frames], [f.get("can_bus") for f in frames])
        for frame, flag, vector in zip(frames, exists, can_bus):
            frame["prev_bev_exists"] = flag
            if vector is not None:
                frame["can_bus"] = vector
        out = frames[-1]
        out["queue"] = frames[:-1]
        out["queue_index"] = np.array(rows, dtype=np.int64)
        return out

    def _frame(self, s: int) -> dict:
        """The fields of sample row `s` on their own (no queue)."""
        out = {"sample_token": str(self.sample_token[s]), "timestamp_us": int(self.timestamp_us[s]),
               "scene_token": str(self.scene_token[s])}
        if self.lidar:
            out["points"], out["lidar_sweeps"] = (self._points(s) if self.sweeps_as == "mmdet3d" else devkit_points(
                self.dataset, out["sample_token"], self.lidar_channel, self.lidar_channel, self.sweeps,
                self.close_radius_m))
        if self.radars:
            out["radar_points"] = radar_points(self.dataset, out["sample_token"], self.radars, self.lidar_channel,
                                               self.radar_sweeps, self.close_radius_m, self.radar_filters)
        if self.boxes:
            out.update(self._boxes(s))
        if self.cameras:
            out.update(self._images(s))
        if self._can_bus is not None:
            out["can_bus"] = self._can_bus[s].copy()
        if self.bev_classes:
            from_lidar = lidar2global(self._lidar_t[s], self._lidar_q[s], self._ego_t[s], self._ego_q[s])
            out["gt_masks_bev"] = bev_mask(self.dataset.map(self._location[s].decode()), from_lidar,
                                           self.bev_classes, self.bev_patch_m, self.bev_canvas)
        return out

    def _read_lidar(self, token: str, filename: str) -> np.ndarray:
        """(P, 5) float32 x, y, z, intensity, ring of one lidar reading, through the sensor reader."""
        frame = self.dataset.sensors.points(token, filename, "lidar", columns=[*XYZI, "ring"])
        values = np.zeros((frame.height, 5), dtype=np.float32)
        for j, name in enumerate(XYZI):  # column by column: a DataFrame's select/to_numpy hang in a forked worker
            values[:, j] = frame.get_column(name).to_numpy()
        if "ring" in frame.columns:
            values[:, 4] = frame["ring"].to_numpy()
        return values

    def _points(self, s: int) -> tuple[np.ndarray, int]:
        """mmdetection3d's LoadPointsFromFile + LoadPointsFromMultiSweeps over the infos' values of sample row s."""
        points = self._read_lidar(self._lidar_token[s].decode(), self._lidar_file[s].decode())
        points[:, 4] = 0
        parts = [points]
        ts = self.timestamp_us[s] / 1e6  # the infos' `timestamp` (seconds)
        lo, hi = self._sweep_offsets[s], self._sweep_offsets[s + 1]
        if hi == lo:  # the converter drops an empty `lidar_sweeps`: then the keyframe pads
            if self.pad_empty_sweeps:
                parts += [remove_close(points, self.close_radius_m)] * self.sweeps
        for w in range(lo, hi):
            sweep = self._read_lidar(self._sweep_token[w].decode(), self._sweep_file[w].decode())
            sweep = remove_close(sweep, self.close_radius_m)
            lidar2sensor = self._sweep_lidar2sensor[w].astype(np.float64)  # np.array of the infos' lists
            sweep[:, :3] = sweep[:, :3] @ lidar2sensor[:3, :3]
            sweep[:, :3] -= lidar2sensor[:3, 3]
            sweep[:, 4] = ts - self._sweep_timestamp_s[w]
            parts.append(sweep)
        return np.concatenate(parts).astype(np.float32, copy=False), int(hi - lo)

    def _boxes(self, s: int) -> dict:
        lo, hi = self._ann_offsets[s], self._ann_offsets[s + 1]
        keep = np.arange(lo, hi)
        if self.box_filter == "valid_flag":
            keep = keep[self._ann_valid[keep]]
        elif self.box_filter == "num_lidar_pts":
            keep = keep[self._ann_num_lidar_pts[keep] > 0]
        boxes = self._ann_box[keep] if self.velocity else self._ann_box[keep, :7]
        return {"gt_bboxes_3d": boxes, "gt_labels_3d": self._ann_label[keep].astype(np.int64),
                "num_lidar_pts": self._ann_num_lidar_pts[keep].astype(np.int64)}

    def _images(self, s: int) -> dict:
        import cv2

        sensors = self.dataset.sensors
        images = []
        for token, filename in zip(self._cam_token[s].tolist(), self._cam_file[s].tolist()):
            data = sensors.file_bytes(token.decode(), filename.decode(), "camera")  # embedded, else the file
            image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)  # = cv2.imread of the file
            images.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB) if self.rgb else image)
        same = len({im.shape for im in images}) == 1
        return {"img": np.stack(images) if same else images, **camera_matrices(self._cam2img[s], self._lidar2cam[s])}


def _text(values: np.ndarray) -> np.ndarray:
    return np.asarray(values.tolist(), dtype=str)


def _bytes(values: np.ndarray) -> np.ndarray:
    """`values` (str) as a fixed-width UTF-8 bytes array of the same shape (decode per item)."""
    return np.char.encode(np.asarray(values.tolist(), dtype=str), "utf-8")


def _sweep_items(computed, picked: np.ndarray) -> np.ndarray:
    """The sweeps (rows of computed.sweep_row) of samples `picked`, in v2_arrays' order."""
    items, _ = gather_segments(offsets(computed.sweep_owner, len(computed.lidar_row)), picked)
    return items
