"""The CLI's plain-text tables (numbers right-aligned, text left-aligned) and `options_from` (what a command sets
itself wins over a parsed flag of the same name)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import polars as pl

from nuparquet.cli.arguments import options_from
from nuparquet.cli.output import format_table


def test_numbers_are_right_aligned_and_text_left_aligned():
    table = format_table(pl.DataFrame({"name": ["a", "bbbbbb"], "count": [7, 12345]}))
    assert table.splitlines() == ["name    count", "------  -----", "a           7", "bbbbbb  12345"]


def test_booleans_print_as_true_and_false_and_nulls_as_blank():
    table = format_table(pl.DataFrame({"key_frame": [True, False, None], "n": [1, 2, 3]}))
    assert table.splitlines() == ["key_frame  n", "---------  -", "true       1", "false      2", "           3"]


def test_a_float_column_has_one_precision_set_by_its_largest_finite_magnitude():
    """3 decimals below 10, 2 from 10 up to 10,000, 1 from 10,000 up (a negative value counts by its size; NaN and
    infinity do not count), each column on its own. Expected cells written by hand."""
    df = pl.DataFrame({
        "small": [1.23456, 9.5, float("nan")],
        "ten": [10.0, 0.126, 1.0],
        "below_10k": [9999.5, 0.5, 2.25],
        "at_10k": [10_000.0, 0.26, 3.0],
        "negative": [-20_000.26, 1.0, float("inf")],
    })
    rows = [line.split() for line in format_table(df).splitlines()[2:]]
    assert rows == [["1.235", "10.00", "9999.50", "10000.0", "-20000.3"],
                    ["9.500", "0.13", "0.50", "0.3", "1.0"],
                    ["nan", "1.00", "2.25", "3.0", "inf"]]


@dataclass(frozen=True)
class _Options:
    scale: float = 1.0
    quiet: bool = False


def test_what_the_command_sets_wins_over_the_parsed_flag_of_the_same_name():
    parsed = argparse.Namespace(scale=0.5, quiet=False, unrelated=3)
    assert options_from(parsed, _Options) == _Options(scale=0.5, quiet=False)
    assert options_from(parsed, _Options, quiet=True) == _Options(scale=0.5, quiet=True)
    assert options_from(argparse.Namespace(), _Options, scale=2.0) == _Options(scale=2.0)


def test_an_optional_number_flag_parses_as_its_number_type(capsys):
    """`fps: float | None` and `workers: int | None` (None: the default rule) give a float and an int from the
    command line, and a non-number is argparse's usage error naming the type, not a crash in the options' checks."""
    import pytest

    from nuparquet.cli.arguments import add_options
    from nuparquet.engine import EngineOptions
    from nuparquet.rendering.video.options import RenderOptions

    parser = argparse.ArgumentParser()
    add_options(parser, RenderOptions)
    add_options(parser, EngineOptions)
    parsed = parser.parse_args(["--fps", "2.5", "--workers", "3"])
    assert (parsed.fps, parsed.workers) == (2.5, 3) and type(parsed.fps) is float and type(parsed.workers) is int
    assert options_from(parsed, EngineOptions).workers == 3
    assert (parser.parse_args([]).fps, parser.parse_args([]).workers) == (None, None)
    with pytest.raises(SystemExit):
        parser.parse_args(["--workers", "two"])
    assert "--workers: invalid int value: 'two'" in capsys.readouterr().err
