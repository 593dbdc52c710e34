"""`nuparquet convert`: nuScenes JSON -> typed tables/ + every registered dataset (`pipeline.py`).

`convert` and `validate` are loaded on first use: importing a light module of this package (`options`, `write`)
must not pull in DuckDB, shapely and every builder (every CLI command imports the convert options to build its
parser; `render` needs only a path check).
"""

from __future__ import annotations

__all__ = ["Validation", "convert", "validate"]


def __getattr__(name: str):
    if name in __all__:
        from nuparquet.conversion import pipeline

        return getattr(pipeline, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
