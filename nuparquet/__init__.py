"""nuparquet: nuScenes-format datasets as typed, denormalised Parquet.

```python
import nuparquet
nuparquet.convert("/data/nuscenes", "v1.0-mini", "nusc.parquet", sensors=("lidar",))
ds = nuparquet.open("nusc.parquet")             # a Dataset: scan, sql, boxes, project_boxes, points, map
ds.boxes(token)                                  # get_sample_data's boxes, for one frame or many
nuparquet.render(ds, "scene-0061", out="scene-0061.mp4", channel="all")
```

The verbs are the CLI's commands under the same names, with the same defaults: `convert`, `validate`,
`export_json` (export-json), `synthesize` (synth), `render` and `render_scenes` (render), `build_index` (index),
`evaluate` (eval), `export_mcap` and `export_mcap_scenes` (export-mcap), `report` (report), `export_coco`
(export-coco: a nuImages conversion's COCO file).
Each takes its options as an options object (`ConvertOptions`, ...) or as keyword fields. Everything loads on
first use, so `import nuparquet` (and the CLI) stays light. The packages that hold the verbs are named for what
they hold (`conversion/`, `rendering/`, ...), never like a verb: importing `nuparquet.render` would otherwise
replace the function `nuparquet.render` with a module.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from nuparquet.version import __version__  # noqa: F401 - nuparquet.__version__

# name -> (module, attribute): the public face, loaded on first use.
_PUBLIC = {
    "Dataset": ("nuparquet.dataset", "Dataset"),
    "convert": ("nuparquet.conversion", "convert"),
    "validate": ("nuparquet.conversion", "validate"),
    "export_json": ("nuparquet.export.json_files", "export_json"),
    "synthesize": ("nuparquet.synth", "synthesize"),
    "render": ("nuparquet.rendering.video.pipeline", "render"),
    "render_scenes": ("nuparquet.rendering.video.batch", "render_scenes"),
    "build_index": ("nuparquet.index.build", "build_index"),
    "evaluate": ("nuparquet.evaluation.run", "evaluate"),
    "export_mcap": ("nuparquet.mcap.export", "export_mcap"),
    "export_mcap_scenes": ("nuparquet.mcap.batch", "export_scenes"),
    "report": ("nuparquet.site.build", "build_report"),
    "export_coco": ("nuparquet.export.coco", "export_coco"),
    "CocoOptions": ("nuparquet.export.coco_options", "CocoOptions"),
    "ConvertOptions": ("nuparquet.conversion.options", "ConvertOptions"),
    "EngineOptions": ("nuparquet.engine.options", "EngineOptions"),
    "EvalOptions": ("nuparquet.evaluation.options", "EvalOptions"),
    "IndexOptions": ("nuparquet.index.options", "IndexOptions"),
    "McapOptions": ("nuparquet.mcap.options", "McapOptions"),
    "RenderOptions": ("nuparquet.rendering.video.options", "RenderOptions"),
    "ReportOptions": ("nuparquet.site.options", "ReportOptions"),
    "SceneSelection": ("nuparquet.dataset.selection", "SceneSelection"),
    "SynthOptions": ("nuparquet.synth.options", "SynthOptions"),
    "NuparquetError": ("nuparquet.errors", "NuparquetError"),
    "UsageError": ("nuparquet.errors", "UsageError"),
    "InputError": ("nuparquet.errors", "InputError"),
    "FormatError": ("nuparquet.errors", "FormatError"),
    "QueryError": ("nuparquet.errors", "QueryError"),
    "EnvironmentFault": ("nuparquet.errors", "EnvironmentFault"),
    "ProblemsFound": ("nuparquet.problems", "ProblemsFound"),
    "UnitsFailed": ("nuparquet.engine.units", "UnitsFailed"),
}

__all__ = [
    "open", "Dataset", "convert", "validate", "export_json", "synthesize", "render", "render_scenes", "build_index",
    "evaluate", "export_mcap", "export_mcap_scenes", "report", "export_coco",
    "CocoOptions", "ConvertOptions", "EngineOptions", "EvalOptions", "IndexOptions", "McapOptions", "RenderOptions", "ReportOptions",
    "SceneSelection", "SynthOptions",
    "NuparquetError", "UsageError", "InputError", "FormatError", "QueryError", "EnvironmentFault", "ProblemsFound",
    "UnitsFailed",
]


def open(path, storage_options=None, *, dataroot=None):  # noqa: A001 - the public name users asked for
    """Open a converted dataset directory: a local path or a URL polars can scan (``s3://bucket/out``, ...), with
    `storage_options` in polars' vocabulary for the manifest and every scan, and `dataroot` where the sensor files
    are if not at the dataroot recorded at conversion. Returns a `Dataset`."""
    from nuparquet.dataset import open_dataset

    return open_dataset(path, storage_options=storage_options, dataroot=dataroot)


def __getattr__(name: str):
    if name in _PUBLIC:
        module, attribute = _PUBLIC[name]
        value = getattr(importlib.import_module(module), attribute)
        globals()[name] = value  # found once
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # for readers and type checkers; at run time the names load on first use
    from nuparquet.conversion import convert, validate
    from nuparquet.conversion.options import ConvertOptions
    from nuparquet.dataset import Dataset
    from nuparquet.engine.options import EngineOptions
    from nuparquet.engine.units import UnitsFailed
    from nuparquet.evaluation.options import EvalOptions
    from nuparquet.evaluation.run import evaluate
    from nuparquet.errors import EnvironmentFault, FormatError, InputError, NuparquetError, QueryError, UsageError
    from nuparquet.export.coco import export_coco
    from nuparquet.export.coco_options import CocoOptions
    from nuparquet.export.json_files import export_json
    from nuparquet.index.build import build_index
    from nuparquet.index.options import IndexOptions
    from nuparquet.mcap.batch import export_scenes as export_mcap_scenes
    from nuparquet.mcap.export import export_mcap
    from nuparquet.mcap.options import McapOptions
    from nuparquet.problems import ProblemsFound
    from nuparquet.rendering.video.batch import render_scenes
    from nuparquet.dataset.selection import SceneSelection
    from nuparquet.rendering.video.options import RenderOptions
    from nuparquet.rendering.video.pipeline import render
    from nuparquet.site.build import build_report as report
    from nuparquet.site.options import ReportOptions
    from nuparquet.synth import synthesize
    from nuparquet.synth.options import SynthOptions
