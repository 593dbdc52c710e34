"""The test cache (`NUPARQUET_TEST_CACHE`, used by the mutation runs) is safe when several pytest-xdist workers ask
for the same generated dataset at once: one builds, the others wait and reuse it, nobody sees half a dataset."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def test_concurrent_workers_build_a_cached_dataset_once_and_all_see_it_whole(tmp_path):
    cache = tmp_path / "cache"
    script = textwrap.dedent(f"""
        import os, sys, time
        sys.path.insert(0, {str(REPO / "tests")!r})
        os.environ["NUPARQUET_TEST_CACHE"] = {str(cache)!r}
        from conftest import generated_root

        def make(root):
            root.mkdir(parents=True)
            (root / "first.json").write_text("x")
            time.sleep(0.5)  # a slow build: the others arrive while it runs
            (root / "last.json").write_text("y")
            with open({str(tmp_path / "builds.log")!r}, "a") as log:
                log.write(str(os.getpid()) + "\\n")

        root = generated_root(None, "synth", make)
        print(sorted(p.name for p in root.iterdir()))
    """)
    workers = [subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True) for _ in range(4)]
    outputs = [w.communicate(timeout=60)[0].strip() for w in workers]
    assert [w.returncode for w in workers] == [0, 0, 0, 0]
    assert outputs == ["['first.json', 'last.json']"] * 4  # every worker saw the whole dataset
    assert len((tmp_path / "builds.log").read_text().split()) == 1  # built once
    assert sorted(p.name for p in cache.iterdir()) == ["synth", "synth.lock"]  # no building folder left
