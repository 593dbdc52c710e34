"""One huge string in a small table must not blow up the conversion's memory (a 40 MB string once took it past
18 GB): measured as the peak RSS of a conversion in its own process."""

from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys

from conftest import SYNTH_VERSION

V = SYNTH_VERSION
LIMIT_MB = 1500  # the same conversion without the string peaks near 250 MB; with it, ~570 MB measured


def test_a_40_mb_string_keeps_memory_bounded_and_round_trips(synth_root, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(synth_root / V, root / V)
    path = root / V / "scene.json"
    records = json.loads(path.read_text())
    records[0]["description"] = "x" * 40_000_000
    path.write_text(json.dumps(records))
    script = ("import sys; from nuparquet.cli.main import main; "
              f"sys.exit(main(['convert', {str(root)!r}, '--version', {V!r}, '--out', {str(tmp_path / 'out')!r}, '--quiet']))")
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    assert done.returncode == 0, done.stderr[-500:]
    assert before / 1024 < LIMIT_MB  # the measurement is this child's, not an earlier larger one
    assert peak_mb < LIMIT_MB, f"peak RSS {peak_mb:.0f} MB"
    from nuparquet.export.json_files import export_json

    export_json(tmp_path / "out", tmp_path / "back")
    again = json.loads((tmp_path / "back" / V / "scene.json").read_text())
    assert again[0]["description"] == records[0]["description"]
