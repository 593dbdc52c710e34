"""nuScenes-lidarseg in the training index: mmdetection3d v1.4.0's `create_nuscenes_infos` adds, when the
devkit has a lidarseg table (`'lidarseg' in nusc.table_names`: VERSION/lidarseg.json exists), after
`valid_flag` of every non-test v1 info

    info['pts_semantic_mask_path'] = osp.join(nusc.dataroot, nusc.get('lidarseg', lidar_token)['filename'])

and `update_infos_to_v2.py` keeps its file name (`Path(...).name`) as the v2 entry's `pts_semantic_mask_path`.
`nusc.get('lidarseg', lidar_token)` finds the record by its own `token`, which nuScenes-lidarseg sets to the
lidar sample_data token."""

from __future__ import annotations

import numpy as np
import polars as pl

from nuparquet.dataset import Dataset
from nuparquet.errors import InputError

LIDARSEG_TABLE = "tables/lidarseg"


def semantic_mask_files(ds: Dataset, lidar_tokens: np.ndarray, sample_tokens: np.ndarray) -> np.ndarray | None:
    """(S,) the lidarseg label file (relative to the dataroot) of each sample's keyframe lidar reading
    `lidar_tokens` (S,); None when the dataset has no lidarseg table (the converter then writes no key).
    A reading without a record stops the converter (KeyError in `nusc.get`): an InputError here."""
    if LIDARSEG_TABLE not in ds.datasets:
        return None
    # the devkit's token index keeps the last record of a token
    table = (ds.scan(LIDARSEG_TABLE).select("token", "filename").collect()
             .unique(subset="token", keep="last", maintain_order=True))
    joined = pl.DataFrame({"token": lidar_tokens}, schema={"token": pl.String}).join(
        table, on="token", how="left", maintain_order="left")
    missing = np.flatnonzero(joined["filename"].is_null().to_numpy())
    if len(missing):
        s = missing[0]
        raise InputError(f"the lidarseg table has no record for the keyframe lidar reading {lidar_tokens[s]} of "
                         f"sample {sample_tokens[s]} ({len(missing)} sample(s) lack one): mmdetection3d's converter "
                         "looks one up for every sample when lidarseg.json is present, and stops there")
    return joined["filename"].to_numpy()
