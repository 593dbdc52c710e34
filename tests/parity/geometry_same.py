"""Comparing what map clients return: shapely geometries spelled out as their parts, then compared exactly, float
arrays within TOLERANCE_M (1e-9 m); the counts say how many float arrays were equal bit for bit and how many only
within the tolerance. Used by tests/parity/test_map_clients.py and benchmarks/bench_map_clients.py."""

from __future__ import annotations

import numpy as np
from shapely.geometry.base import BaseGeometry

TOLERANCE_M = 1e-9


def canonical(value):
    """A value with every shapely geometry, set and numpy scalar spelled out as plain, comparable parts."""
    if isinstance(value, BaseGeometry):
        if value.geom_type == "Polygon":
            return ("Polygon", canonical(value.exterior), [canonical(ring) for ring in value.interiors])
        if hasattr(value, "geoms"):
            return (value.geom_type, [canonical(part) for part in value.geoms])
        return (value.geom_type, np.asarray(value.coords))
    if isinstance(value, dict):
        return {key: canonical(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(canonical(item) for item in value)
    if isinstance(value, (set, frozenset)):
        return ("set", sorted(value))
    if isinstance(value, np.generic):
        return (type(value).__name__, value.item())
    return value


def differences(ours, theirs, path="value", found=None, counts=None) -> list[str]:
    """Where two canonical values differ beyond TOLERANCE_M; `counts` gathers how many float arrays were equal
    bit for bit ("exact") and how many only within the tolerance ("close")."""
    found = [] if found is None else found
    if len(found) >= 5:
        return found
    if type(ours) is not type(theirs):
        found.append(f"{path}: type {type(ours).__name__} vs {type(theirs).__name__}")
    elif isinstance(theirs, np.ndarray):
        if ours.dtype != theirs.dtype or ours.shape != theirs.shape:
            found.append(f"{path}: {ours.dtype}{ours.shape} vs {theirs.dtype}{theirs.shape}")
        elif np.array_equal(ours, theirs, equal_nan=theirs.dtype.kind == "f"):
            if counts is not None and theirs.dtype.kind == "f":
                counts["exact"] += 1
        elif theirs.dtype.kind == "f" and np.allclose(ours, theirs, rtol=0.0, atol=TOLERANCE_M, equal_nan=True):
            if counts is not None:
                counts["close"] += 1
        else:
            worst = np.nanmax(np.abs(ours - theirs)) if theirs.dtype.kind == "f" else "n/a"
            found.append(f"{path}: arrays differ (largest {worst}): {ours!r} vs {theirs!r}")
    elif isinstance(theirs, dict):
        if list(ours) != list(theirs):
            found.append(f"{path}: keys {list(ours)} vs {list(theirs)}")
        else:
            for key in theirs:
                differences(ours[key], theirs[key], f"{path}[{key!r}]", found, counts)
    elif isinstance(theirs, (list, tuple)):
        if len(ours) != len(theirs):
            found.append(f"{path}: length {len(ours)} vs {len(theirs)}")
        else:
            for i, (a, b) in enumerate(zip(ours, theirs)):
                differences(a, b, f"{path}[{i}]", found, counts)
    elif isinstance(theirs, float):
        if not (ours == theirs or abs(ours - theirs) <= TOLERANCE_M or (np.isnan(ours) and np.isnan(theirs))):
            found.append(f"{path}: {ours!r} vs {theirs!r}")
    elif ours != theirs:
        found.append(f"{path}: {ours!r} vs {theirs!r}")
    return found


def assert_same(ours, theirs, what: str) -> dict:
    counts = {"exact": 0, "close": 0}
    found = differences(canonical(ours), canonical(theirs), counts=counts)
    assert not found, f"{what}: " + "; ".join(found)
    return counts
