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


def test_conversions_are_cached_only_for_dataroots_that_outlive_the_session(tmp_path, tmp_path_factory, monkeypatch):
    """NUPARQUET_TEST_CACHE_CONVERSIONS (mutation groups no conversion runs): a conversion of a dataroot outside the
    session's temporary folder is made once and reused; one of a root made in the session is made every time."""
    import nuparquet.conversion
    from conftest import converted

    made = []

    def fake_convert(root, version, out, **options):
        Path(out).mkdir(parents=True)
        (Path(out) / "manifest.json").write_text(f"{root} {version} {options}")
        made.append(Path(out))

    monkeypatch.setattr(nuparquet.conversion, "convert", fake_convert)
    monkeypatch.setenv("NUPARQUET_TEST_CACHE_CONVERSIONS", str(tmp_path / "conversions"))
    lasting = REPO / "schemas"  # any folder outside the session's temporary folder
    first = converted(tmp_path_factory, "lasting", lasting, "v1", sensors=("lidar",))
    again = converted(tmp_path_factory, "lasting", lasting, "v1", sensors=("lidar",))
    other = converted(tmp_path_factory, "lasting", lasting, "v1")
    assert first == again and len(made) == 2 and other != first  # options are part of the key
    assert first.is_relative_to(tmp_path / "conversions") and (first / "manifest.json").is_file()
    session_root = tmp_path / "data"
    assert converted(tmp_path_factory, "fresh", session_root, "v1") != converted(tmp_path_factory, "fresh",
                                                                                   session_root, "v1")
    assert len(made) == 4
