"""Hand-made mutants: the changes mutmut does not make (a statement deleted, two arguments of a call swapped, one
variable read for another), listed in `mutation/hand_mutants.toml`, each applied alone to a staging copy and run
against its group's tests (`mutation/run.py`'s GROUPS).

    python mutation/hand.py                      # every hand mutant
    python mutation/hand.py engine map           # the hand mutants of some groups
    python mutation/hand.py --name engine-forget-before-rerun    # some by name
    python mutation/run.py --hand [GROUP ...]    # the same, from the mutation runner

Each group's selection first runs unmutated in the staging copy (`.mutation/hand/`): a failing baseline would make
every mutant look killed, so its mutants are then reported as errors. A mutant is then "killed" (a selected test
failed: pytest's exit code 1, the first failing test is recorded), "survived" (all passed), "timeout" (past the
limit: an endless loop is detected too) or "error" (pytest could not run: exit 2-5). The staging copy is on
PYTHONPATH, so CLI subprocesses and process-pool workers run the mutant as well. Results are merged into
`.mutation/hand/results.json`; `mutation/report.py` shows them with each mutant's reason and judgement.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import GROUPS, REPO, STAGING, copy_tree, group_env  # noqa: E402

HAND_MUTANTS = Path(__file__).resolve().parent / "hand_mutants.toml"
WHERE = STAGING / "hand"
RESULTS = WHERE / "results.json"
LIMIT_S = 900  # per mutant: a survivor runs the group's whole selection


def load() -> list[dict]:
    """The hand mutants, checked: unique names, a known group, an original text found exactly once in its file."""
    mutants = tomllib.loads(HAND_MUTANTS.read_text())["mutant"]
    names = [m["name"] for m in mutants]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(f"hand mutant names repeat: {duplicates}")
    for m in mutants:
        if m["group"] not in GROUPS:
            raise ValueError(f"{m['name']}: unknown group {m['group']}")
        found = (REPO / m["file"]).read_text().count(m["original"])
        if found != 1:
            raise ValueError(f"{m['name']}: the original text occurs {found} times in {m['file']}, not once")
    return mutants


def _pytest(group: str, tests: list[str] | None, env: dict) -> tuple[str, float, str]:
    args = tests or GROUPS[group].pytest_args()
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", *args]
    started = time.monotonic()
    try:
        done = subprocess.run(command, cwd=WHERE, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    except subprocess.TimeoutExpired:
        return "timeout", time.monotonic() - started, ""
    seconds = time.monotonic() - started
    failed = re.findall(r"^(?:FAILED|ERROR) (\S+)", done.stdout, re.M)
    verdict = {0: "survived", 1: "killed"}.get(done.returncode, "error")
    detail = failed[0] if failed else ("" if verdict != "error" else done.stdout[-2000:] + done.stderr[-2000:])
    return verdict, seconds, detail


def run(mutants: list[dict]) -> dict[str, dict]:
    """Apply each mutant alone in `.mutation/hand/`, run its group's tests, restore; the results by name."""
    copy_tree(WHERE)
    shutil.rmtree(WHERE / "groups", ignore_errors=True)  # cached conversions: made again by each baseline
    # tests find the real data at REPO/../shared: beside the staging copy too (else a mutant's `tests` naming a real
    # extract case would skip, and pass)
    shared = WHERE.parent / "shared"
    if (REPO.parent / "shared").is_dir() and not shared.exists():
        shared.symlink_to(REPO.parent / "shared")
    results = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    baseline: dict[str, tuple[str, str]] = {}
    for m in mutants:
        group = m["group"]
        env = group_env(group, WHERE / "groups" / group) | {"PYTHONPATH": str(WHERE)}
        if group not in baseline:  # the unmutated selection must pass (and makes the cached conversions)
            verdict, seconds, detail = _pytest(group, None, env)
            baseline[group] = (verdict, detail)
            print(f"[{group}] baseline: {'passes' if verdict == 'survived' else verdict} ({seconds:.0f} s)", flush=True)
        if baseline[group][0] != "survived":
            results[m["name"]] = {"verdict": "error", "seconds": 0, "detail": f"baseline {baseline[group]}"}
            continue
        path = WHERE / m["file"]
        original = path.read_text()
        path.write_text(original.replace(m["original"], m["replacement"], 1))
        try:
            verdict, seconds, detail = _pytest(group, m.get("tests"), env)
        finally:
            path.write_text(original)
        results[m["name"]] = {"verdict": verdict, "seconds": round(seconds, 1), "detail": detail,
                              "date": time.strftime("%Y-%m-%d")}
        print(f"[{group}] {m['name']}: {verdict} ({seconds:.0f} s) {detail[:200]}", flush=True)
        RESULTS.write_text(json.dumps(results, indent=1, sort_keys=True))
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("groups", nargs="*", metavar="GROUP", help="the hand mutants of these groups (default all)")
    parser.add_argument("--name", nargs="+", default=[], help="only these hand mutants")
    args = parser.parse_args(argv)
    mutants = load()
    unknown = [g for g in args.groups if g not in GROUPS]
    if unknown:
        parser.error(f"unknown group(s) {', '.join(unknown)}")
    chosen = [m for m in mutants if (not args.groups or m["group"] in args.groups)
              and (not args.name or m["name"] in args.name)]
    if args.name and len(chosen) != len(set(args.name)):
        parser.error(f"unknown hand mutant(s): {sorted(set(args.name) - {m['name'] for m in chosen})}")
    run(chosen)
    return 0


if __name__ == "__main__":
    sys.exit(main())
