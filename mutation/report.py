"""Print the figures and surviving mutants of the last `mutation/run.py` runs as Markdown (for MUTATION.md).

    python mutation/report.py [GROUP ...]

Reads `.mutation/<group>/mutants/mutmut-cicd-stats.json` (mutmut's own figures) and `survivors.diff`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

STAGING = Path(__file__).resolve().parent.parent / ".mutation"


def main(groups: list[str]) -> int:
    groups = groups or sorted(p.name for p in STAGING.iterdir() if (p / "survivors.txt").exists())
    for group in groups:
        where = STAGING / group
        stats = json.loads((where / "mutants" / "mutmut-cicd-stats.json").read_text())
        print(f"### {group}\n")
        print("| " + " | ".join(stats) + " |")
        print("|" + "---|" * len(stats))
        print("| " + " | ".join(str(v) for v in stats.values()) + " |\n")
        diff = (where / "survivors.diff").read_text() if (where / "survivors.diff").exists() else ""
        for block in diff.split("## ")[1:]:
            name, *lines = block.strip().splitlines()
            print(f"- `{name.split('.')[-1]}`: " + " / ".join(f"`{line.strip()}`" for line in lines if line.startswith("+")))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
