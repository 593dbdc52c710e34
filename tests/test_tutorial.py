"""docs/tutorial.ipynb (the devkit tutorials' path in nuparquet) runs from top to bottom on the dataset it makes, and
is committed without outputs: executed here so that it can never rot."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest

NOTEBOOK = Path(__file__).resolve().parent.parent / "docs" / "tutorial.ipynb"


def test_the_notebook_is_committed_without_outputs():
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert len(code) > 40
    assert all(cell.outputs == [] and cell.execution_count is None for cell in code)


def test_the_tutorial_runs_from_top_to_bottom(tmp_path, monkeypatch):
    from nbclient import NotebookClient

    monkeypatch.setenv("NUPARQUET_TUTORIAL_DIR", str(tmp_path / "work"))
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError naming the cell and its traceback
    errors = [out for cell in notebook.cells if cell.cell_type == "code" for out in cell.outputs
              if out.output_type == "error"]
    assert errors == []
    pictures = sum("image/png" in out.get("data", {}) for cell in notebook.cells if cell.cell_type == "code"
                   for out in cell.outputs)
    assert pictures >= 27  # every kind of picture was drawn (the family section adds 2)
    assert (tmp_path / "work" / "scene.mp4").is_file() and (tmp_path / "work" / "scene.frames.parquet").is_file()


pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_from_devkit_counts_match_its_table():
    """docs/from-devkit.md: the counts it states are those of its table."""
    import re
    from collections import Counter

    text = (NOTEBOOK.parent / "from-devkit.md").read_text()
    rows = [line.split("|")[1:-1] for line in text.splitlines() if re.match(r"^\| \d+ \|", line)]
    assert [int(r[0]) for r in rows] == list(range(1, len(rows) + 1))
    status = Counter(r[-1].strip() for r in rows)
    assert set(status) == {"covered", "not supported"}
    stated = re.search(r"Counts: (\d+) calls; (\d+) covered, (\d+) not supported", text)
    assert tuple(map(int, stated.groups())) == (len(rows), status["covered"], status["not supported"])
    for tutorial, words in (("nuScenes", "nuScenes"), ("Map", "map expansion"), ("CAN bus", "CAN bus"),
                            ("lidarseg", "lidarseg/panoptic")):
        mine = Counter(r[-1].strip() for r in rows if r[1].strip() == tutorial)
        assert f"{words} {sum(mine.values())} ({mine['covered']} covered" in " ".join(text.split())
