"""The figures and surviving mutants of the last `mutation/run.py` runs, and the hand-made mutants' verdicts, as the
Markdown of MUTATION.md.

    python mutation/report.py [GROUP ...]

For each group staged under `.mutation/<group>/` (in `run.GROUPS` order), mutmut's own status of every mutant
(`mutmut results --all true`), restricted to the group's sample when the run sampled (`sample.txt`, its seed in
`result.json`). A first-run survivor that a re-check (`run.py GROUP --recheck NAMES`, `.mutation/<group>-recheck/`)
kills counts as killed since; each remaining survivor is shown with its change and the judgement recorded under the
group in `mutation/judgements.toml` (equivalent, with why; or killed by a named test, checked by hand; or left). A
survivor killed by a test only checked by hand (no re-check has run it) is shown in its own column and is not counted
as detected: the score is the tool's verdicts only,

    (killed + timeout + segfault + killed since) / (checked - equivalent)

where a timeout (an endless loop) and a segfault (the test process crashed) are detections, and "checked" counts
every mutant the run reached. The hand-made mutants (`mutation/hand_mutants.toml`, run by `mutation/hand.py`) follow,
with their verdicts from `.mutation/hand/results.json`.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import GROUPS, mutant_change  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
STAGING = REPO / ".mutation"
JUDGEMENTS = Path(__file__).resolve().parent / "judgements.toml"
HAND_MUTANTS = Path(__file__).resolve().parent / "hand_mutants.toml"
HAND_RESULTS = STAGING / "hand" / "results.json"
MUTMUT = [sys.executable, "-m", "mutmut"]
DETECTED = ("killed", "timeout", "segfault")


def statuses(where: Path) -> dict[str, str]:
    listed = subprocess.run(MUTMUT + ["results", "--all", "true"], cwd=where, capture_output=True, text=True).stdout
    return {line.split(": ")[0].strip(): line.split(": ")[1].strip() for line in listed.splitlines() if ": " in line}


def change(where: Path, name: str) -> str:
    old, new = mutant_change(where, name)
    return f"`{' / '.join(old)}` -> `{' / '.join(new)}`" if old or new else "(no diff)"


def group_report(group: str, judgements: dict[str, str]) -> tuple[str, dict]:
    where = STAGING / group
    status = statuses(where)
    sample = (where / "sample.txt").read_text().split() if (where / "sample.txt").is_file() else None
    result = json.loads((where / "result.json").read_text()) if (where / "result.json").is_file() else {}
    considered = {n: s for n, s in status.items() if sample is None or n in sample}
    counts = Counter(considered.values())
    checked = sum(v for k, v in counts.items() if k != "not checked")
    detected = sum(counts[k] for k in DETECTED)
    # the verdicts of a re-check (`run.py GROUP --recheck NAMES`: every selected test, current tests) replace the
    # first run's for the mutants it ran
    recheck_dir = STAGING / f"{group}-recheck"
    rechecked = {n: s for n, s in statuses(recheck_dir).items() if s != "not checked"} if recheck_dir.is_dir() else {}
    lines, equivalent, killed_since, killed_by_hand, left = [], 0, 0, 0, 0
    for name, first in sorted(considered.items()):
        if first in DETECTED or first == "not checked":
            continue
        state = rechecked.get(name, first)
        if state in DETECTED:
            killed_since += 1
            continue
        # keys: the full name (quoted in TOML: it holds dots) or, in the first runs' judgements, the name after the module
        verdict = judgements.get(name) or judgements.get(name.rsplit(".", 1)[-1])
        if verdict and verdict.startswith("equivalent"):
            equivalent += 1
        elif verdict and verdict.startswith("killed"):  # by a test checked by hand: not the tool's verdict, so
            killed_by_hand += 1                         # shown apart and left out of the score
        else:
            left += 1
        state = f"{first}, re-checked: {state}" if name in rechecked else state
        lines.append(f"- `{name}` ({state}): {change(where, name)}  \n  "
                     + (f"**{verdict.split(':')[0]}**:{verdict.split(':', 1)[1]}" if verdict and ":" in verdict
                        else "**not equivalent, left**"))
    denominator = checked - equivalent
    seed = (result.get("sample") or {}).get("seed")
    figures = {"group": group, "mutants": len(status), "sample": len(sample) if sample else None, "seed": seed,
               "checked": checked, "not_checked": counts["not checked"], "killed": counts["killed"],
               "timeout": counts["timeout"], "segfault": counts["segfault"], "survived": counts["survived"],
               "no_tests": counts["no tests"], "equivalent": equivalent, "killed_since": killed_since,
               "killed_by_hand": killed_by_hand, "left": left,
               "score_tool": detected / denominator if denominator else None,
               "score_now": (detected + killed_since) / denominator if denominator else None}
    return "\n".join(lines), figures


def hand_report() -> tuple[str, dict[str, Counter]]:
    """The hand-made mutants' table (one row each) and the verdicts counted per group."""
    mutants = tomllib.loads(HAND_MUTANTS.read_text())["mutant"]
    results = json.loads(HAND_RESULTS.read_text()) if HAND_RESULTS.is_file() else {}
    per_group: dict[str, Counter] = {}
    rows = ["| group | hand mutant | kind | module | verdict | killed by / judgement |", "|---|---|---|---|---|---|"]
    for m in sorted(mutants, key=lambda m: (list(GROUPS).index(m["group"]), m["name"])):
        found = results.get(m["name"], {})
        verdict = found.get("verdict", "not run")
        judgement = m.get("judgement", "")
        if verdict == "survived" and judgement.startswith("equivalent"):
            verdict = "survived (equivalent)"
        per_group.setdefault(m["group"], Counter())[verdict] += 1
        detail = (f"`{found.get('detail', '').split('::')[-1]}`" if verdict == "killed" and found.get("detail")
                  else judgement or ("" if verdict != "survived" else "**not equivalent, left**"))
        rows.append(f"| {m['group']} | {m['name']} | {m['kind']} | `{m['file'].removeprefix('nuparquet/')}` | "
                    f"{verdict} | {detail} |")
    return "\n".join(rows), per_group


def main(groups: list[str]) -> int:
    judgements = tomllib.loads(JUDGEMENTS.read_text()) if JUDGEMENTS.is_file() else {}
    groups = groups or [g for g in GROUPS if (STAGING / g / "mutants").is_dir()]
    rows, sections = [], []
    for group in groups:
        text, figures = group_report(group, judgements.get(group, {}))
        rows.append(figures)
        sections.append(f"### {group}\n\n{text or '(none)'}\n")
    print("| group | mutants | sample (seed) | checked | killed | timeout | segfault | survived | no tests | "
          "equivalent | killed since (re-check) | killed (by hand only) | left | score (tool run) | score now |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for f in rows:
        score = lambda v: f"**{v:.1%}**" if v is not None else "—"  # noqa: E731
        sample = f"{f['sample']} ({f['seed']})" if f["sample"] else "all"
        print(f"| {f['group']} | {f['mutants']} | {sample} | {f['checked']} | {f['killed']} | "
              f"{f['timeout']} | {f['segfault']} | {f['survived']} | {f['no_tests']} | {f['equivalent']} | "
              f"{f['killed_since']} | {f['killed_by_hand']} | {f['left']} | {score(f['score_tool'])} | "
              f"{score(f['score_now'])} |")
    total = {k: sum(f[k] for f in rows) for k in ("checked", "killed", "timeout", "segfault", "equivalent",
                                                   "killed_since")}
    denominator = total["checked"] - total["equivalent"]
    if denominator:
        detected = total["killed"] + total["timeout"] + total["segfault"]
        print(f"\nAll groups: {detected} detected by the tool run of {denominator} non-equivalent checked mutants "
              f"= **{detected / denominator:.1%}**; with the {total['killed_since']} killed since: "
              f"**{(detected + total['killed_since']) / denominator:.1%}**.\n")
    table, per_group = hand_report()
    print("\n## Hand-made mutants\n")
    print(", ".join(f"{g}: {c['killed']}/{sum(c.values())} killed" for g, c in per_group.items()) + "\n")
    print(table + "\n")
    print("\n## Surviving mutants\n")
    print("\n".join(sections))
    (STAGING / "report.json").write_text(json.dumps({"groups": rows, "hand": {g: dict(c) for g, c in per_group.items()}},
                                                    indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
