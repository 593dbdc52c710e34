"""Options of library functions, declared once: a dataclass field with `option(...)` is both the keyword a
notebook user passes and the CLI flag `nuparquet.cli.arguments.add_options` generates from it.

```python
@dataclass
class RenderOptions:
    channel: str | None = option(None, help="camera to render")
    scale: float = option(0.5, help="output size relative to the images")
```

The flag name is the field name with dashes (`all_frames` -> `--all-frames`); the argparse type, choices and
boolean handling come from the field's type annotation (`bool`, `int`, `float`, `str`, `Path`, `Literal[...]`,
`X | None`, `tuple[str, ...]` for a comma-separated or repeated list).

Every verb of the library has one calling contract, `verb(dataset, what, out, options=None, *, engine=None,
on_progress=None, **fields)`: the dataset it reads (a `Dataset` or a path), what it works on (a scene, a
`SceneSelection`, a results file), where it writes (`out`: never a field of an options object), and how
(`options`, which hold settings only). Settings come as an options object, as keyword fields, or both, merged one
way (`resolve`, `resolve_all`): a keyword may set a field the object leaves at its default; a keyword that says
otherwise than a field the object set is an error. Values are checked once, when the object is built
(`__post_init__`, with `check_choices` for every `Literal` field); checks that need the machine or the data (is
Ray installed, does the scene exist) run in the verb.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

_MISSING = dataclasses.MISSING
T = TypeVar("T")


def option(default: Any = _MISSING, *, help: str, flag: str | None = None, metavar: str | None = None,  # noqa: A002
           choices: tuple | None = None, cli: bool = True, default_factory: Any = _MISSING) -> Any:
    """A dataclass field that is also a CLI flag.

    default: the default (omit for a required option); help: the flag's help text (also the field's doc);
    flag: the flag spelling if not `--field-name`; metavar, choices: as argparse (choices default to a
    `Literal`'s values); cli=False keeps the field out of the CLI (library-only, e.g. callbacks).
    """
    metadata = {"help": help, "flag": flag, "metavar": metavar, "choices": choices, "cli": cli}
    if default_factory is not _MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def _default(f: dataclasses.Field) -> Any:
    if f.default_factory is not _MISSING:
        return f.default_factory()
    return f.default


def resolve(options_class: type[T], options: T | None, fields: dict[str, Any]) -> T:
    """The options a verb runs with: `options` (or the class's defaults) with `fields` setting the fields the object
    leaves at their defaults.

    Raises TypeError naming an unknown field and the valid ones (a typo must not be silently ignored), an object of
    another class, or a keyword that contradicts a field the object set (`RenderOptions(scale=1.0)` with
    `scale=0.5`: which one was meant cannot be known)."""
    declared = {f.name: f for f in dataclasses.fields(options_class) if f.init}
    unknown = sorted(set(fields) - set(declared))
    if unknown:
        raise TypeError(f"unknown option(s) {', '.join(unknown)} for {options_class.__name__}; "
                        f"valid: {', '.join(sorted(declared))}")
    if options is None:
        return options_class(**fields)
    if not isinstance(options, options_class):
        raise TypeError(f"expected {options_class.__name__}, got {type(options).__name__}")
    conflicts = [name for name, value in fields.items()
                 if getattr(options, name) != value and getattr(options, name) != _default(declared[name])]
    if conflicts:
        raise TypeError(f"option(s) {', '.join(sorted(conflicts))} given both in the {options_class.__name__} object "
                        "and as keywords, with other values: give each once")
    return dataclasses.replace(options, **fields) if fields else options


def resolve_all(fields: dict[str, Any], *given: tuple[type, Any]) -> tuple:
    """Each (options class, object or None) of `given` resolved with its share of the keyword `fields` (`split_fields`):
    what every verb that takes several option objects (settings, engine) does with its keywords."""
    parts = split_fields(fields, *(options_class for options_class, _ in given))
    return tuple(resolve(options_class, options, part) for (options_class, options), part in zip(given, parts))


def check_choices(options) -> None:
    """UsageError naming the flag for every `Literal[...]` field of the dataclass `options` whose value is not one of
    its choices (the CLI's argparse choices say the same; this holds for library callers)."""
    import typing

    from nuparquet.errors import UsageError

    hints = typing.get_type_hints(type(options))
    for f in dataclasses.fields(options):
        hint = hints[f.name]
        if typing.get_origin(hint) is typing.Literal:
            valid = f.metadata.get("choices") or typing.get_args(hint)
            value = getattr(options, f.name)
            if value not in valid:
                flag = f.metadata.get("flag") or "--" + f.name.replace("_", "-")
                raise UsageError(f"{flag} must be one of {', '.join(map(str, valid))}, got {value!r}")


def split_fields(fields: dict[str, Any], *classes: type) -> list[dict[str, Any]]:
    """`fields` split by the option class that declares each (the first that does); a field no class declares
    is a TypeError listing the valid names. One dict per class, in order."""
    parts: list[dict[str, Any]] = [{} for _ in classes]
    names = [{f.name for f in dataclasses.fields(c) if f.init} for c in classes]
    for key, value in fields.items():
        owner = next((i for i, known in enumerate(names) if key in known), None)
        if owner is None:
            valid = sorted(set().union(*names))
            raise TypeError(f"unknown option {key!r}; valid: {', '.join(valid)}")
        parts[owner][key] = value
    return parts
