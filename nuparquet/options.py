"""Options of library functions, declared once: a dataclass field with `option(...)` is both the keyword a
notebook user passes and the CLI flag `nuparquet.cli.arguments.add_options` generates from it.

```python
@dataclass
class RenderOptions:
    scene: str = option(help="scene name", positional=False)
    scale: float = option(0.5, help="output size relative to the images")
```

The flag name is the field name with dashes (`all_frames` -> `--all-frames`); the argparse type, choices and
boolean handling come from the field's type annotation (`bool`, `int`, `float`, `str`, `Path`, `Literal[...]`,
`X | None`, `tuple[str, ...]` for a comma-separated or repeated list).
"""

from __future__ import annotations

import dataclasses
from typing import Any

_MISSING = dataclasses.MISSING


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
