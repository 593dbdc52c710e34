"""What the tracking evaluation can be asked to do, declared once: each field is a keyword of `TrackingOptions`
and a flag of the CLI (`nuparquet.cli.arguments.add_options`). Settings only: the submission and the output
directory are the arguments of `evaluate_tracking`. Light on purpose: a parser is built from it without loading
the evaluation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from nuparquet.options import option

_BY_HELP = ("distance, visibility, location, night, rain, scene, or any column of the annotations or scenes "
            "datasets")


@dataclass
class TrackingOptions:
    """A tracking evaluation: which split, which configuration, which slices, which outputs."""

    split: str = option("val", help="the split evaluated: train, val, test, mini_train, mini_val, train_detect, "
                        "train_track, or a custom split of <dataroot>/<version>/splits.json (default val)")
    config: str = option("tracking_nips_2019", metavar="NAME",
                         help="the devkit's tracking configuration by name (default tracking_nips_2019)")
    config_file: str | Path | None = option(
        None, metavar="CONFIG.json", help="a tracking configuration in the devkit's JSON format instead of --config")
    by: tuple[str, ...] = option((), metavar="DIM,...", help=f"also evaluate per slice of {_BY_HELP} "
                                 "(comma-separated for several)")
    bins: tuple[str, ...] = option(
        (), metavar="EDGES", help="bin edges for --by distance (metres, default 0,10,20,30,40,50) and numeric "
        "columns, e.g. 0,20,40")
    plots: bool = option(True, help="write the devkit's tracking curves as PNG into DIR/plots (--no-plots: skip)")
    overwrite: bool = option(False, help="replace DIR if it already holds files")
