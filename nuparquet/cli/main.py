"""`nuparquet` entry point: one subcommand per module in this package, each with `register(subparsers)`.

Exit codes: 0 success, 1 the command ran and found problems (or failed on the data), 2 usage errors.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from nuparquet.version import __version__
from nuparquet.errors import NuparquetError

# Subcommand modules, in the order `--help` lists them.
COMMANDS = ["convert", "validate", "export_json", "synth", "info", "stats", "sql", "render", "index", "eval",
            "export_mcap", "report", "export_coco"]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or only of `command` (a name as typed, e.g. "export-json"): a command's run
    then imports no other command's options (start-up is part of every command's time)."""
    parser = argparse.ArgumentParser(
        prog="nuparquet",
        description="Convert nuScenes-format datasets to typed, denormalised Parquet; query and render them.",
    )
    parser.add_argument("--version", action="version", version=f"nuparquet {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS if command is None else [command.replace("-", "_")]:
        importlib.import_module(f"nuparquet.cli.{name}").register(sub)
    return parser


def _command(argv: list[str]) -> str | None:
    """The command `argv` names when it is the first argument (else None: `--help`, `--version`, a typo)."""
    first = argv[0] if argv else None
    return first if first is not None and first.replace("-", "_") in COMMANDS and "_" not in first else None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(_command(argv)).parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except NuparquetError as exc:  # user-facing errors: a message, never a traceback
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception:  # a damaged output (a truncated Parquet file) is named, not shown as a traceback
        damaged = _damaged_files(args)
        if not damaged:
            raise
        path, reason = damaged[0]
        more = f" (and {len(damaged) - 1} more)" if len(damaged) > 1 else ""
        print(f"error: {path} is damaged ({reason}){more}; convert the dataset again", file=sys.stderr)
        return 1


def _damaged_files(args) -> list[tuple[str, str]]:
    """Unreadable Parquet files of the converted output the command was reading, if any."""
    target = getattr(args, "out", None) if args.command in ("info", "stats", "sql") else getattr(args, "dataset", None)
    if target is None:
        return []
    try:
        from nuparquet.dataset import open_dataset

        ds = open_dataset(target)
        return [] if ds.is_remote else ds.damaged_files()
    except Exception:  # noqa: BLE001 - the original error is the one to show then
        return []


if __name__ == "__main__":
    sys.exit(main())
