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

Every verb of the library takes its options the same way (`resolve`): an options object, keyword fields, or
both (the keywords then replace fields of the object). Values are checked once, when the object is built
(`__post_init__`); checks that need the machine or the data (is Ray installed, does the scene exist) run in
the verb.
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


def resolve(options_class: type[T], options: T | None, fields: dict[str, Any]) -> T:
    """The options a verb runs with: `options` (or the class's defaults) with `fields` replacing its values.

    Raises TypeError naming an unknown field and the valid ones (a typo must not be silently ignored)."""
    names = {f.name for f in dataclasses.fields(options_class) if f.init}
    unknown = sorted(set(fields) - names)
    if unknown:
        raise TypeError(f"unknown option(s) {', '.join(unknown)} for {options_class.__name__}; "
                        f"valid: {', '.join(sorted(names))}")
    if options is None:
        return options_class(**fields)
    if not isinstance(options, options_class):
        raise TypeError(f"expected {options_class.__name__}, got {type(options).__name__}")
    return dataclasses.replace(options, **fields) if fields else options


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
