"""Exact comparison of devkit answers: equal values of the same Python types, dicts in the same key order, lists in
the same order, numpy arrays of the same dtype and shape with equal elements (NaN equal to NaN)."""

from __future__ import annotations

import math

import numpy as np


def differences(ours, theirs, path: str = "", limit: int = 5) -> list[str]:
    """Where `ours` and `theirs` differ (empty when they are the same)."""
    found: list[str] = []
    _walk(ours, theirs, path or "value", found, limit)
    return found


def assert_same(ours, theirs, what: str = "") -> None:
    found = differences(ours, theirs)
    assert not found, f"{what}: " + "; ".join(found)


def _walk(a, b, path: str, found: list[str], limit: int) -> None:
    if len(found) >= limit:
        return
    if isinstance(b, np.ndarray) or isinstance(a, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            found.append(f"{path}: {type(a).__name__} vs {type(b).__name__}")
        elif a.dtype != b.dtype or a.shape != b.shape:
            found.append(f"{path}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}")
        elif not np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"):
            found.append(f"{path}: {a!r} vs {b!r}")
        return
    if type(a) is not type(b):
        found.append(f"{path}: type {type(a).__name__} vs {type(b).__name__} ({a!r} vs {b!r})")
        return
    if isinstance(b, dict):
        if list(a) != list(b):
            found.append(f"{path}: keys {list(a)} vs {list(b)}")
            return
        for key in b:
            _walk(a[key], b[key], f"{path}[{key!r}]", found, limit)
    elif isinstance(b, (list, tuple)):
        if len(a) != len(b):
            found.append(f"{path}: length {len(a)} vs {len(b)}")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            _walk(x, y, f"{path}[{i}]", found, limit)
    elif isinstance(b, float):
        if not (a == b or (math.isnan(a) and math.isnan(b))):
            found.append(f"{path}: {a!r} vs {b!r}")
    elif isinstance(b, (str, int, bool, type(None))):
        if a != b:
            found.append(f"{path}: {a!r} vs {b!r}")
    else:
        raise TypeError(f"{path}: cannot compare {type(b).__name__}")
