"""CLI flags generated from option dataclasses (`nuparquet.options.option`), and options built back from the
parsed arguments: the flags are never copied by hand."""

from __future__ import annotations

import argparse
import dataclasses
import types
import typing
from pathlib import Path
from typing import Any, Literal

FORMATS = ("table", "csv", "json")  # how info, stats and sql print (`cli.output`)


def _unwrap_optional(hint: Any) -> Any:
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return rest[0] if len(rest) == 1 else hint
    return hint


def _comma_list(text: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in text.split(",") if part.strip())


def add_options(parser: argparse.ArgumentParser, options_class: type, *, skip: tuple[str, ...] = (),
                defaults: dict[str, Any] | None = None, aliases: dict[str, tuple[str, ...]] | None = None,
                help: dict[str, str] | None = None) -> None:  # noqa: A002 - argparse's word
    """Add one flag per CLI field of `options_class` (a dataclass using `option`), except those in `skip`.

    Required fields (no default) become required flags. `defaults` overrides a default for this parser only;
    `aliases` gives a field more spellings on this parser (`{"workers": ("--jobs",)}`); `help` another help text
    (a command that gives the field its own meaning, as `report --scenes`).
    """
    aliases = aliases or {}
    helps = help or {}
    hints = typing.get_type_hints(options_class)
    defaults = defaults or {}
    for f in dataclasses.fields(options_class):
        meta = f.metadata
        if not meta.get("cli", False) or f.name in skip:
            continue
        hint = _unwrap_optional(hints[f.name])
        flag = meta.get("flag") or "--" + f.name.replace("_", "-")
        kwargs: dict[str, Any] = {"dest": f.name, "help": helps.get(f.name, meta["help"])}
        default = defaults.get(f.name, f.default if f.default is not dataclasses.MISSING else dataclasses.MISSING)
        if f.default_factory is not dataclasses.MISSING and f.name not in defaults:
            default = f.default_factory()
        if default is dataclasses.MISSING:
            kwargs["required"] = True
        else:
            kwargs["default"] = default
        if hint is bool:
            kwargs["action"] = argparse.BooleanOptionalAction if default is True else "store_true"
        elif typing.get_origin(hint) is Literal:
            kwargs["choices"] = meta.get("choices") or typing.get_args(hint)
            kwargs["type"] = type(typing.get_args(hint)[0])
        elif typing.get_origin(hint) is tuple:
            kwargs["type"] = _comma_list
        else:
            kwargs["type"] = Path if hint is Path else hint if hint in (int, float, str) else str
            if meta.get("choices"):
                kwargs["choices"] = meta["choices"]
        if meta.get("metavar"):
            kwargs["metavar"] = meta["metavar"]
        parser.add_argument(flag, *aliases.get(f.name, ()), **kwargs)


def options_from(args: argparse.Namespace, options_class: type, *, unset: tuple[str, ...] = (), **overrides: Any):
    """An `options_class` instance from parsed arguments (fields absent from `args` keep their defaults, and so do
    the fields of `unset` that the command line left at None: a flag shared by two option classes with other
    defaults, as `render --scale`)."""
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(options_class)
              if f.init and hasattr(args, f.name) and not (f.name in unset and getattr(args, f.name) is None)}
    return options_class(**(values | overrides))


def opened(args: argparse.Namespace):
    """The dataset `args.dataset` names, opened with `--dataroot` when the command has it (`SensorFiles`)."""
    from nuparquet.dataset import open_dataset

    return open_dataset(args.dataset, dataroot=getattr(args, "dataroot", None))
