"""What every canned query shares: its inputs (a Dataset or LazyFrames), the scene filter, small helpers."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, TypeAlias

import polars as pl

if TYPE_CHECKING:
    from nuparquet.dataset import Dataset

    Source: TypeAlias = Dataset | pl.LazyFrame | pl.DataFrame  # a Dataset, or the LazyFrame a query names
    Scene: TypeAlias = str | Sequence[str] | None

US_PER_S = 1_000_000
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def lazy_of(source, name: str) -> pl.LazyFrame:
    """`source` as the LazyFrame of dataset `name`: scanned from a Dataset, or taken as given."""
    if isinstance(source, pl.LazyFrame):
        return source
    if isinstance(source, pl.DataFrame):
        return source.lazy()
    if hasattr(source, "scan"):
        return source.scan(name)
    raise TypeError(f"expected a nuparquet Dataset or the {name!r} LazyFrame, got {type(source).__name__}")


def second_of(source, given, name: str) -> pl.LazyFrame:
    """The second input of a two-dataset query: `given`, or scanned from `source` when that is a Dataset."""
    if given is not None:
        return lazy_of(given, name)
    if hasattr(source, "scan"):
        return source.scan(name)
    raise TypeError(f"pass {name}= (a LazyFrame) or a Dataset as the first argument")


def for_scene(lf: pl.LazyFrame, scene: str | Sequence[str] | None, column: str = "scene_name") -> pl.LazyFrame:
    if scene is None:
        return lf
    if isinstance(scene, str):
        return lf.filter(pl.col(column) == scene)
    return lf.filter(pl.col(column).is_in(list(scene)))


def mean_std(expr: pl.Expr, name: str) -> list[pl.Expr]:
    return [expr.mean().alias(f"{name}_mean"), expr.std(ddof=0).alias(f"{name}_std")]


def group_keys(by_scene: bool, *rest: str) -> list[str]:
    return (["scene_name"] if by_scene else []) + list(rest)
