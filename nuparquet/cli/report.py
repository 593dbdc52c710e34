"""`nuparquet report OUT --out DIR [--scenes A,B | --where SQL]`: the dataset as a static web site.

The flags are generated from `ReportOptions` and `EngineOptions` (`nuparquet.cli.arguments.add_options`); only
`OUT` and `--quiet` are the CLI's own.
"""

from __future__ import annotations

import argparse
import sys

from nuparquet.cli.arguments import add_options, opened, options_from
from nuparquet.dataset.selection import SceneSelection
from nuparquet.sensors.options import SensorFiles
from nuparquet.cli.progress import bars
from nuparquet.engine.options import EngineOptions
from nuparquet.site.options import ReportOptions

_EPILOG = """\
examples:
  nuparquet report OUT --out report/                       # then open report/index.html in a browser
  nuparquet report OUT --out report/ --scenes scene-0061,scene-0103
  nuparquet report OUT --out report/ --where "log_location = 'boston-seaport'" --engine ray
  nuparquet report OUT --out report/ --no-videos           # statistics and scene table only, no sensor files read

DIR/index.html opens from disk with no network (no CDN: every style, script, chart and video is inside DIR):
the dataset's facts, the canned statistics of `nuparquet stats` as tables and charts, and a scene table
(location, local time and time of day, weather and light words of the description, duration, counts) that sorts
by any column and filters by text and location. Each scene has a page with its video (every camera tiled with
the bird's-eye view, H.264, rendered through the many-scene render: --engine, --workers), keyframe renderings
(the default camera with boxes and lidar points) and its CAN bus plots. A scene whose images are missing gets a
page that says so. The folder is written beside DIR and renamed into place when complete.
"""


def register(sub) -> None:
    p = sub.add_parser(
        "report",
        help="write a static web report of a converted dataset (scenes, statistics, videos)",
        description="Write a static web site about a converted dataset: facts, statistics, charts, a sortable "
        "scene table and one page per scene with its video, keyframe renderings and CAN bus plots.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dataset", metavar="OUT", help="a directory written by `nuparquet convert`")
    p.add_argument("--out", metavar="DIR", required=True,
                   help="the folder to write (DIR/index.html, one page per scene, assets)")
    add_options(p, SceneSelection, skip=("all_scenes",), help={
        "scenes": "only these scenes (comma-separated names) in the scene table and pages",
        "where": "only the scenes matching this SQL condition on the scenes dataset, e.g. \"log_location = "
                 "'boston-seaport'\" (combined with --scenes if both are given)"})
    add_options(p, ReportOptions)
    add_options(p, SensorFiles)
    add_options(p, EngineOptions, skip=("keep_going", "resume"))
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args) -> int:
    from nuparquet.site.build import build_report

    result = build_report(opened(args), options_from(args, SceneSelection), args.out, options_from(args, ReportOptions),
                          engine=options_from(args, EngineOptions), on_progress=bars(not args.quiet))
    print(f"wrote the report of {len(result.scenes)} scene(s) -> {result.index}")
    for scene, reason in result.problems.items():
        print(f"warning: {scene}: {reason}", file=sys.stderr)
    return 0
