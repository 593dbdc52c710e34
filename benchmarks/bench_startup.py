"""Start-up: `nuparquet --help` and `import nuparquet` (issue 22: the front door must not make the CLI slower).

    .venv/bin/python benchmarks/bench_startup.py [--repeats 20]

Each a fresh process, interleaved with the bare interpreter (`python -c pass`, the reference: what no Python
program can go below), medians over the repeats. `import nuparquet` loads the lazy front door only (no polars,
numpy or OpenCV until a verb is called); `nuparquet --help` builds the whole parser, every subcommand's flags
generated from the option classes. Wall time and peak RSS of each process.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def run(repeats: int = 20) -> dict:
    from harness import NUPARQUET, PYTHON, Row, log, megabytes, run_child, summarize

    commands = {"bare": [PYTHON, "-c", "pass"], "import": [PYTHON, "-c", "import nuparquet"],
                "help": [*NUPARQUET, "--help"]}
    log(f"start-up: {', '.join(' '.join(c[-2:]) for c in commands.values())} ({repeats} each, interleaved)")
    runs: dict[str, list] = {name: [] for name in commands}
    for _ in range(repeats):  # interleaved: a busy moment hits all three alike
        for name, command in commands.items():
            runs[name].append(run_child(command))
    figures = {name: summarize(r) for name, r in runs.items()}
    bare = figures["bare"]["wall_s"]

    def row(row_id: str, name: str, what: str) -> Row:
        ours = figures[name]
        return Row(id=row_id, benchmark=what, ours=f"{ours['wall_s'] * 1000:.0f} ms, {megabytes(ours['max_rss_mb'])} peak",
                   reference=f"bare interpreter {bare * 1000:.0f} ms", ratio=f"{ours['wall_s'] / bare:.2f}x",
                   target="no slower than before issue 22 (see the before/after table)", met=None)

    return {"name": "startup", "commands": {name: " ".join(map(str, c)) for name, c in commands.items()},
            **{name: figures[name] for name in commands},
            "rows": [row("s1", "import", "`import nuparquet` (the lazy front door)"),
                     row("s2", "help", "`nuparquet --help` (every subcommand's parser)")]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    from harness import report_alone

    report_alone(run(args.repeats))


if __name__ == "__main__":
    main()
