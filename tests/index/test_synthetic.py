"""The index on synthetic data (no reference needed): structure, sweeps along the prev chain, split
assignment from the devkit's scene lists, and the clear errors for missing inputs."""

from __future__ import annotations

import json
import pickle

import numpy as np
import polars as pl
import pytest

from nuparquet.dataset import Dataset, open_dataset
from nuparquet.errors import InputError, UsageError
from nuparquet.index import IndexOptions, build_index
from nuparquet.index.bevformer import frame_indices
from nuparquet.index.labels import CLASSES
from nuparquet.index.splits import assign_splits


@pytest.fixture(scope="session")
def synth_infos(synth_out, tmp_path_factory):
    out = tmp_path_factory.mktemp("synth-index")
    build_index(synth_out, str(out / "v2"), IndexOptions(version="v1.0-trainval", max_sweeps=3))
    build_index(synth_out, str(out / "v1"), IndexOptions(version="v1.0-trainval", info_version=1, max_sweeps=3))
    return out


def test_structure_against_the_json_tables(synth_root, synth_infos):
    tables = synth_root / "v1.0-synth"
    sample = json.loads((tables / "sample.json").read_text())
    sample_data = {r["token"]: r for r in json.loads((tables / "sample_data.json").read_text())}
    anns = json.loads((tables / "sample_annotation.json").read_text())
    info = pickle.loads((synth_infos / "v1" / "nuscenes_infos_train.pkl").read_bytes())["infos"]
    assert [i["token"] for i in info] == [s["token"] for s in sample]  # both synth scenes are in train
    for i in info:
        assert len(i["gt_boxes"]) == sum(a["sample_token"] == i["token"] for a in anns)
        # sweeps: the prev chain from the keyframe lidar reading, at most 3, newest first
        lidar = next(r for r in sample_data.values() if r["sample_token"] == i["token"] and r["is_key_frame"]
                     and "LIDAR_TOP" in r["filename"])
        chain, token = [], lidar["prev"]
        while token and len(chain) < 3:
            chain.append(token)
            token = sample_data[token]["prev"]
        assert [s["sample_data_token"] for s in i["sweeps"]] == chain
        for s in i["sweeps"]:  # a sweep's own pose maps to the keyframe lidar: R orthonormal
            r = s["sensor2lidar_rotation"]
            assert np.allclose(r @ r.T, np.eye(3), atol=1e-9)
    v2 = pickle.loads((synth_infos / "v2" / "nuscenes_infos_train.pkl").read_bytes())
    assert [e["sample_idx"] for e in v2["data_list"]] == list(range(len(sample)))
    assert (synth_infos / "v2" / "infos" / "train.parquet").is_file()
    assert pickle.loads((synth_infos / "v2" / "nuscenes_infos_val.pkl").read_bytes())["data_list"] == []


def test_a_test_version_has_no_instances_even_over_annotated_data(synth_root, synth_out, tmp_path):
    """`--version v1.0-test` over a dataset with annotations: v1.4.0's infos of a test version have no gt_* keys
    (`if not test`), and update_nuscenes_infos builds instances and cam_instances only `if 'gt_boxes' in
    ori_info_dict`: every v2 entry keeps the template's empty `instances` and has no `cam_instances`, and the
    metainfo ignores no class; the Parquet rows hold empty lists."""
    anns = json.loads((synth_root / "v1.0-synth" / "sample_annotation.json").read_text())
    samples = json.loads((synth_root / "v1.0-synth" / "sample.json").read_text())
    assert anns  # the data reach the case
    build_index(synth_out, str(tmp_path / "v1"), IndexOptions(version="v1.0-test", info_version=1))
    build_index(synth_out, str(tmp_path / "v2"), IndexOptions(version="v1.0-test"))
    v1 = pickle.loads((tmp_path / "v1" / "nuscenes_infos_test.pkl").read_bytes())["infos"]
    assert len(v1) == len(samples) and not any(k.startswith("gt_") or k == "valid_flag" for i in v1 for k in i)
    v2 = pickle.loads((tmp_path / "v2" / "nuscenes_infos_test.pkl").read_bytes())
    assert v2["metainfo"]["categories"] == {name: i for i, name in enumerate(CLASSES)}
    assert [e["token"] for e in v2["data_list"]] == [i["token"] for i in v1]
    for entry in v2["data_list"]:
        assert list(entry)[-1] == "instances" and entry["instances"] == []  # and no cam_instances
    rows = pl.read_parquet(tmp_path / "v2" / "infos" / "test.parquet")
    assert rows["instances"].to_list() == [[]] * len(samples)
    assert all(v == [] for cams in rows["cam_instances"].to_list() for v in cams.values())


def test_split_assignment_follows_the_devkit_lists():
    from nuscenes.utils import splits

    names = np.array([splits.train[0], splits.val[0], "scene-unknown", splits.mini_train[0], splits.mini_val[0]])
    tokens = np.array([f"t{i}" for i in range(len(names))])
    sample_scene = np.repeat(tokens, 2)
    trainval = assign_splits("v1.0-trainval", tokens, names, sample_scene)
    expect = ["train" if n in splits.train else "val" for n in names]
    assert list(trainval[::2]) == expect and list(trainval[1::2]) == expect
    mini = assign_splits("v1.0-mini", tokens, names, sample_scene)
    assert list(mini[::2]) == ["train" if n in splits.mini_train else "val" for n in names]
    assert set(assign_splits("v1.0-test", tokens, names, sample_scene)) == {"test"}


def test_frame_idx_restarts_after_the_last_sample_of_a_scene():
    nxt = np.array(["a", "b", "", "c", "", "d", "e", ""])
    assert frame_indices(np.zeros(8), nxt).tolist() == [0, 1, 2, 0, 1, 0, 1, 2]


def test_missing_inputs_are_named(synth_out, tmp_path):
    ds = open_dataset(synth_out)
    manifest = dict(ds.manifest, datasets={k: v for k, v in ds.manifest["datasets"].items() if k != "annotations"})
    with pytest.raises(InputError, match="annotations"):
        build_index(Dataset(ds.root, manifest), str(tmp_path / "a"), IndexOptions(version="v1.0-trainval"))
    without_can_bus = dict(ds.manifest, datasets={k: v for k, v in ds.manifest["datasets"].items()
                                                  if k != "sample_can_bus"})
    with pytest.raises(InputError, match="sample_can_bus"):
        build_index(Dataset(ds.root, without_can_bus), str(tmp_path / "b"), IndexOptions(version="v1.0-trainval",
                                                                    format="bevformer", info_version=1))
    with pytest.raises(UsageError, match="--version"):
        build_index(ds, str(tmp_path / "c"))


def test_cli_writes_the_files(synth_out, tmp_path):
    from nuparquet.cli.main import main

    assert main(["index", str(synth_out), "--out", str(tmp_path / "o"), "--version", "v1.0-trainval",
                 "--split", "train", "--quiet"]) == 0
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["infos", "nuscenes_infos_train.pkl"]
    assert main(["index", str(synth_out), "--out", str(tmp_path / "p"), "--version", "v1.0-trainval",
                 "--split", "test"]) == 2


def test_cameras_given_as_comma_separated_text_are_the_channels_in_that_order():
    """A library caller may give `cameras` as the CLI's text: "CAM_BACK, CAM_FRONT" is those two channels, in that
    order (the order of each info's `cams` / `images`), as the tuple gives them."""
    assert "o", IndexOptions(cameras="CAM_BACK, CAM_FRONT,").cameras == ("CAM_BACK", "CAM_FRONT")
    assert "o", IndexOptions(cameras=("CAM_BACK", "CAM_FRONT")).cameras == ("CAM_BACK", "CAM_FRONT")
    with pytest.raises(UsageError, match="--cameras must name at least one camera channel"):
        "o", IndexOptions(cameras=" , ")


@pytest.mark.parametrize("fields, parquet_step", [({}, True), ({"parquet": False}, False),
                                                  ({"info_version": 1}, False)])
def test_progress_counts_the_steps_it_names(synth_out, tmp_path, fields, parquet_step):
    """The progress total is the number of steps reported, known from the start: reading, computing and splitting,
    then per split the pickle and, for v2 infos with `parquet` (the default), the Parquet rows. v1 infos write no
    Parquet whatever `parquet` says, so they have no such step (a bar that ends at 4 of 5 would look stuck)."""
    events = []
    build_index(synth_out, str(tmp_path / "o"), IndexOptions(version="v1.0-test", **fields),
                on_progress=events.append)
    steps = [e.step for e in events if e.step]
    assert steps == ["read tables", "compute", "splits", *(["parquet test"] if parquet_step else []), "write test"]
    assert {e.total for e in events} == {len(steps)}
    assert events[-1].finished and events[-1].done == len(steps)
    assert (tmp_path / "o" / "infos").exists() == parquet_step
