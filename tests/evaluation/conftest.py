"""The evaluation's test data: a synthetic dataroot named v1.0-trainval (so the devkit evaluates its scenes
that are in the real val list: scene-0003, scene-0012, scene-0013), edited for the hard cases
(`eval_edits`), converted once; the devkit's NuScenes over it; and the submissions made from it."""

from __future__ import annotations

from pathlib import Path

import pytest


EVAL_VERSION = "v1.0-trainval"
EVAL_SCENES = 13  # scene-0001 .. scene-0013: three of them in the devkit's val split


@pytest.fixture(scope="session")
def eval_data(tmp_path_factory) -> tuple[Path, dict]:
    from nuparquet.synth import synthesize
    from eval_edits import edit_dataset

    root = synthesize(tmp_path_factory.mktemp("eval-synth") / "data", scenes=EVAL_SCENES, samples_per_scene=6,
                      seed=3, version=EVAL_VERSION, with_can_bus=False)
    return root, edit_dataset(root, EVAL_VERSION)


@pytest.fixture(scope="session")
def eval_root(eval_data) -> Path:
    return eval_data[0]


@pytest.fixture(scope="session")
def eval_edits(eval_data) -> dict:
    return eval_data[1]


@pytest.fixture(scope="session")
def eval_out(eval_root, tmp_path_factory) -> Path:
    from nuparquet.convert import convert

    out = tmp_path_factory.mktemp("eval-out") / "out"
    convert(eval_root, EVAL_VERSION, out)
    return out


@pytest.fixture(scope="session")
def eval_nusc(devkit, eval_root):
    return devkit.NuScenes(EVAL_VERSION, str(eval_root), verbose=False)


@pytest.fixture(scope="session")
def submissions(eval_nusc, eval_edits, tmp_path_factory) -> dict[str, Path]:
    """name -> results.json: perfect, noisy (two seeds), edge cases."""
    import eval_submissions as make

    folder = tmp_path_factory.mktemp("eval-submissions")
    files = {"perfect": make.write(folder / "perfect.json", make.perfect(eval_nusc)),
             "noisy": make.write(folder / "noisy.json", make.noisy(eval_nusc, seed=1)),
             "noisy2": make.write(folder / "noisy2.json", make.noisy(eval_nusc, seed=2))}
    results, _ = make.edge_cases(eval_nusc, eval_edits)
    files["edges"] = make.write(folder / "edges.json", results)
    return files


@pytest.fixture(scope="session")
def edge_placement(eval_nusc, eval_edits) -> dict:
    import eval_submissions as make

    return make.edge_cases(eval_nusc, eval_edits)[1]
