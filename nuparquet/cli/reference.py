"""docs/cli.md: the `--help` of `nuparquet` and of every command, generated from the parser (the help texts users
read are behaviour: a stale or broken one fails `tests/cli/test_cli_reference.py`).

    python -m nuparquet.cli.reference --docs docs/cli.md     # or `make docs`
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

from nuparquet.cli.main import build_parser

WIDTH = 100  # the help is wrapped at this many columns, whatever the terminal (argparse reads $COLUMNS otherwise)


def _fixed_width(parser: argparse.ArgumentParser, width: int) -> argparse.ArgumentParser:
    """`parser` formatting its help at `width` columns (its own formatter class kept: raw epilogs stay raw)."""
    parser.formatter_class = functools.partial(parser.formatter_class, width=width)
    return parser


def help_texts(width: int = WIDTH) -> dict[str, str]:
    """{"nuparquet": the top-level `--help`, "nuparquet CMD": each command's `--help`}, in the order `--help` lists
    the commands, as printed at `width` columns."""
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    texts = {parser.prog: _fixed_width(parser, width).format_help()}
    for sub in commands.choices.values():
        texts[sub.prog] = _fixed_width(sub, width).format_help()
    return texts


def reference_markdown() -> str:
    """The command-line reference: every `--help`, in Markdown."""
    texts = help_texts()
    out = ["# nuparquet command line", "",
           f"Every command's `--help`, as printed at {WIDTH} columns. Generated from the parser (`nuparquet/cli/`) by "
           "`python -m nuparquet.cli.reference --docs docs/cli.md` (`make docs`). Do not edit by hand.", "",
           "Commands: " + ", ".join(f"[`{prog.split(' ', 1)[1]}`](#{prog.replace(' ', '-')})"
                                    for prog in list(texts)[1:]) + ".", ""]
    for prog, text in texts.items():
        out += [f"## {prog}", "", "```text", text.rstrip("\n"), "```", ""]
    return "\n".join(out)


if __name__ == "__main__":
    cli = argparse.ArgumentParser(description="Print or write the command-line reference (docs/cli.md).")
    cli.add_argument("--docs", metavar="PATH", help="write the Markdown reference to PATH")
    args = cli.parse_args()
    markdown = reference_markdown()
    if args.docs:
        Path(args.docs).parent.mkdir(parents=True, exist_ok=True)
        Path(args.docs).write_text(markdown)
    else:
        print(markdown, end="")
