"""`sample_can_bus/`: one row per sample with the CAN bus aligned to it (`nuparquet.can_bus.align`) and the
BEVFormer-family `can_bus` vector, exact and corrected (`nuparquet.can_bus.bevformer`)."""

from __future__ import annotations

import polars as pl

from nuparquet.can_bus.align import aligned
from nuparquet.can_bus.bevformer import can_bus_vectors
from nuparquet.columns import to_series
from nuparquet.conversion.builders.common import samples
from nuparquet.conversion.builder import BuildContext, Builder
from nuparquet.sources.can_bus import FOLDER, META, ROUTE


def build(ctx: BuildContext) -> pl.DataFrame:
    rows = (samples(ctx).select("sample_token", "scene_token", "scene_name", pl.col("sample_timestamp").alias("timestamp"))
            .sort("scene_name", "timestamp", "sample_token"))
    messages = {name.split("/", 1)[1]: name for name in ctx.written()
                if name.startswith(f"{FOLDER}/") and name.split("/", 1)[1] not in (META, ROUTE)}
    columns = [rows]
    poses, pose_keys = None, []
    for message, name in sorted(messages.items()):
        frame = ctx.dataset(name).collect()
        columns.append(aligned(rows, message, frame))
        if message == "pose":
            poses = frame
            pose_keys = next((f["keys"] for f in ctx.files if f["dataset"] == name), frame.columns[1:])
    exact, corrected = can_bus_vectors(rows, poses, pose_keys)
    has_poses = ~pl.Series(corrected[:, 0]).is_nan().to_numpy()
    columns.append(pl.DataFrame([to_series("can_bus", exact),
                                 to_series("can_bus_corrected", corrected, valid=has_poses)]))
    return pl.concat(columns, how="horizontal")


BUILDER = Builder("sample_can_bus", build, scope="whole", schema="sample_can_bus", needs=("can_bus",))
