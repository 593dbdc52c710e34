"""docs/cli.md is every command's `--help` as the parser prints it: the help texts users read are behaviour, and a
changed one (a flag added, a description edited) must show in the committed reference."""

from __future__ import annotations

import sys

import pytest

from conftest import REPO
from nuparquet.cli.main import COMMANDS
from nuparquet.cli.reference import help_texts, reference_markdown

REGENERATE = "python -m nuparquet.cli.reference --docs docs/cli.md (or make docs)"


@pytest.mark.skipif(sys.version_info[:2] != (3, 11), reason="docs/cli.md is Python 3.11's argparse output (the "
                    "Makefile's python3.11); other versions lay help out slightly differently")
def test_committed_cli_reference_is_generated_from_the_parser():
    committed = (REPO / "docs" / "cli.md").read_text()
    assert committed == reference_markdown(), f"docs/cli.md is stale: regenerate it with {REGENERATE}"


def test_the_reference_holds_every_command_in_order_whatever_the_terminal_width(monkeypatch, capsys):
    texts = help_texts()
    assert list(texts) == ["nuparquet", *(f"nuparquet {c.replace('_', '-')}" for c in COMMANDS)]
    from nuparquet.cli.main import main

    monkeypatch.setenv("COLUMNS", "300")  # a wide terminal's `--help`: the same text, other line breaks
    for prog, text in texts.items():
        with pytest.raises(SystemExit) as exit_:
            main([*prog.split()[1:], "--help"])
        assert exit_.value.code == 0
        assert "".join(capsys.readouterr().out.split()) == "".join(text.split()), prog
    monkeypatch.setenv("COLUMNS", "40")
    assert help_texts() == texts
