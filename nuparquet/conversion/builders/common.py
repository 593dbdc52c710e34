"""Inputs several builders share, memoised on the build context (computed once per conversion)."""

from __future__ import annotations

import polars as pl

from nuparquet.conversion import lookups
from nuparquet.conversion.builder import BuildContext


def samples(ctx: BuildContext) -> pl.DataFrame:
    """`lookups.sample_lookup`: sample_token -> scene, log location, sample timestamp."""
    return ctx.shared("samples", lambda: lookups.sample_lookup(ctx.tables))


def reference_poses(ctx: BuildContext) -> pl.DataFrame:
    """`lookups.reference_poses`: per sample, the reference lidar keyframe's timestamp and ego translation."""
    return ctx.shared("reference_poses", lambda: lookups.reference_poses(ctx.tables, samples(ctx)))
