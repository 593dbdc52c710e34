"""Every public callable of the devkit's faces (`nuparquet.devkit...`) takes the devkit's parameters, in its order,
with its defaults: code that calls a devkit method by keyword or leaves an argument out gets the devkit's meaning.
Ours may add keyword-only parameters (`parquet=`, `storage_options=`, ...) after the devkit's. Not compared: a method of
ours that forwards `*args, **kwargs` (the renderers, checked by their own parity tests), and the database classes'
`dataroot=None` (found from the converted output, where the devkit has a fixed default path: `ALLOWED`)."""

from __future__ import annotations

import enum
import importlib
import inspect
import warnings

import numpy as np
import pytest

pytestmark = pytest.mark.devkit

# (our module, its devkit's module, the names to compare: classes (their public methods) and functions)
PAIRS = [
    ("nuparquet.devkit.nuscenes", "nuscenes.nuscenes", ("NuScenes", "NuScenesExplorer")),
    ("nuparquet.devkit.map_expansion.map_api", "nuscenes.map_expansion.map_api",
     ("NuScenesMap", "NuScenesMapExplorer")),
    ("nuparquet.devkit.map_expansion.arcline_path_utils", "nuscenes.map_expansion.arcline_path_utils",
     ("discretize", "discretize_lane", "length_of_lane", "project_pose_to_lane", "get_curvature_at_distance_along_lane",
      "pose_at_length", "compute_segment_sign", "get_transformation_at_step", "apply_affine_transformation",
      "principal_value")),
    ("nuparquet.devkit.can_bus.can_bus_api", "nuscenes.can_bus.can_bus_api", ("NuScenesCanBus",)),
    ("nuparquet.devkit.prediction", "nuscenes.prediction", ("PredictHelper",)),
    ("nuparquet.devkit.prediction.input_representation.static_layers",
     "nuscenes.prediction.input_representation.static_layers", ("StaticLayerRasterizer",)),
    ("nuparquet.devkit.prediction.input_representation.agents",
     "nuscenes.prediction.input_representation.agents", ("AgentBoxesWithFadedHistory",)),
    ("nuparquet.devkit.prediction.input_representation.combinators",
     "nuscenes.prediction.input_representation.combinators", ("Rasterizer",)),
    ("nuparquet.devkit.utils.geometry_utils", "nuscenes.utils.geometry_utils",
     ("view_points", "box_in_image", "transform_matrix", "points_in_box")),
    ("nuparquet.devkit.utils.splits", "nuscenes.utils.splits", ("create_splits_logs", "create_splits_scenes")),
    ("nuparquet.devkit.truckscenes", "truckscenes.truckscenes", ("TruckScenes",)),
]


ALLOWED = {("NuScenes", "dataroot"), ("NuScenesCanBus", "dataroot"), ("TruckScenes", "dataroot")}


def _forwards(function) -> bool:
    kinds = {p.kind for p in inspect.signature(function).parameters.values()}
    return inspect.Parameter.VAR_POSITIONAL in kinds and inspect.Parameter.VAR_KEYWORD in kinds


def _same(a, b) -> bool:
    if a is b:
        return True
    if isinstance(a, enum.Enum) and isinstance(b, enum.Enum):  # our BoxVisibility mirrors the devkit's enum
        return type(a).__name__ == type(b).__name__ and a.name == b.name and a.value == b.value
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)
    return type(a) is type(b) and a == b


def _callables(module, names):
    for name in names:
        obj = getattr(module, name, None)
        if obj is None:
            continue
        if inspect.isclass(obj):
            yield name, obj.__init__
            for attr, member in vars(obj).items():
                if callable(member) and not attr.startswith("_"):
                    yield f"{name}.{attr}", member
                elif isinstance(member, (staticmethod, classmethod)) and not attr.startswith("_"):
                    yield f"{name}.{attr}", member.__func__
        else:
            yield name, obj


def _parameters(function) -> list[inspect.Parameter]:
    return [p for p in inspect.signature(function).parameters.values()
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) or p.kind == p.KEYWORD_ONLY]


@pytest.mark.parametrize("ours_name,theirs_name,names", PAIRS, ids=[p[0].removeprefix("nuparquet.devkit.")
                                                                      for p in PAIRS])
def test_our_faces_take_the_devkits_parameters_and_defaults(ours_name, theirs_name, names):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            theirs = importlib.import_module(theirs_name)
        except ImportError as exc:  # truckscenes-devkit's explorer wants open3d; the class itself does not
            pytest.fail(f"{theirs_name} does not import: {exc}")
    ours = importlib.import_module(ours_name)
    ours_callables = dict(_callables(ours, names))
    compared, differences = 0, []
    for qualified, theirs_function in _callables(theirs, names):
        ours_function = ours_callables.get(qualified)
        if ours_function is None or not callable(theirs_function) or _forwards(ours_function):
            continue
        try:
            expected = _parameters(theirs_function)
        except (TypeError, ValueError):
            continue
        got = {p.name: p for p in _parameters(ours_function)}
        got_order = [p.name for p in _parameters(ours_function)]
        for position, parameter in enumerate(expected):
            mine = got.get(parameter.name)
            if mine is None:
                if parameter.kind != parameter.VAR_KEYWORD:
                    differences.append(f"{qualified}: no parameter {parameter.name!r}")
                continue
            if parameter.kind != parameter.KEYWORD_ONLY and got_order.index(parameter.name) != position:
                differences.append(f"{qualified}: {parameter.name!r} at position {got_order.index(parameter.name)},"
                                   f" the devkit's at {position}")
            if (qualified, parameter.name) not in ALLOWED and not _same(parameter.default, mine.default):
                differences.append(f"{qualified}({parameter.name}=): {mine.default!r}, the devkit's "
                                   f"{parameter.default!r}")
        compared += 1
    assert compared >= len(names), (compared, names)
    assert differences == []
