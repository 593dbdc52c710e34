"""Which scenes a many-scene job takes (`render`, `export-mcap`, `report`: one output per scene): the selection
flags, declared once, and the scene names they pick from a dataset. Light on purpose (no polars at import): every
CLI command builds its parser from `SceneSelection`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from nuparquet.errors import QueryError, UsageError
from nuparquet.options import option


@dataclass
class SceneSelection:
    """Which scenes a many-scene job takes (the folder their outputs go to is the verb's `out` argument)."""

    all_scenes: bool = option(False, help="every scene of the dataset, one output each into --out-dir")
    scenes: tuple[str, ...] = option(
        (), metavar="A,B,...", help="these scenes (comma-separated names), one output each into --out-dir")
    where: str | None = option(
        None, metavar="SQL", help="the scenes matching this SQL condition on the scenes dataset, e.g. "
        "\"log_location = 'boston-seaport' AND nbr_samples > 30\" (combined with --scenes if both are given)")
    def __post_init__(self) -> None:
        scenes = self.scenes.split(",") if isinstance(self.scenes, str) else self.scenes
        self.scenes = tuple(name.strip() for name in scenes if name.strip())

    @property
    def many(self) -> bool:
        """A many-scene job was asked for (rather than one --scene)."""
        return self.all_scenes or bool(self.scenes) or self.where is not None

    @property
    def subset(self) -> bool:
        """Fewer than every scene may be taken (--scenes or --where)."""
        return bool(self.scenes) or self.where is not None

    def check(self, *, default_all: bool = False) -> None:
        """UsageError unless the selection names scenes (`default_all`: taking none means every scene, as a report
        does) without contradicting itself."""
        if not default_all and not (self.all_scenes or self.scenes or self.where is not None):
            raise UsageError("say which scenes to take (--all-scenes, --scenes A,B or --where SQL)")
        if self.all_scenes and (self.scenes or self.where is not None):
            raise UsageError("--all-scenes takes every scene; leave out --scenes and --where, or --all-scenes")


def check_out_dir(out_dir) -> Path:
    """The folder a many-scene job writes into, as a Path: UsageError if none is given or it is a file."""
    if out_dir is None:
        raise UsageError("--all-scenes, --scenes and --where write one file per scene: give --out-dir DIR")
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise UsageError(f"--out-dir {out_dir} is a file; give a directory")
    return Path(out_dir)


def scene_job(dataset, selection: SceneSelection, out) -> tuple:
    """What a many-scene verb checks before any work, in its order: `out` a folder (`check_out_dir`), the dataset
    opened (`as_dataset`), the selection coherent, its scenes in the dataset. Returns (dataset, scene names, out
    folder)."""
    from nuparquet.dataset.core import as_dataset

    out_dir = check_out_dir(out)
    dataset = as_dataset(dataset)
    selection.check()
    return dataset, select_scenes(dataset, selection.scenes, selection.where), out_dir


def select_scenes(dataset, scenes: tuple[str, ...] = (), where: str | None = None) -> list[str]:
    """The scene names of `dataset` that `scenes` (names; empty: all) and `where` (SQL on the scenes dataset) pick,
    sorted by name.

    Raises:
        UsageError: a name the dataset does not hold (`Dataset.check_scenes`), nothing selected.
        QueryError: a `where` condition polars cannot parse or run.
    """
    import polars as pl

    if where is not None:
        try:
            names = dataset.scan("scenes").filter(pl.sql_expr(where)).select("name").collect()["name"].to_list()
        except (pl.exceptions.PolarsError, ValueError) as exc:  # a bad column, a syntax error
            raise QueryError(f"--where {where!r}: {exc}".splitlines()[0]) from None
    else:
        names = dataset.scene_names()
    if scenes:
        dataset.check_scenes(scenes)
        wanted = set(scenes)
        names = [name for name in names if name in wanted]
    if not names:
        raise UsageError("no scene selected" + (f" by --where {where!r}" if where else ""))
    return sorted(set(names))
