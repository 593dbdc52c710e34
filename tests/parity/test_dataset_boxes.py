"""`Dataset.boxes` and `Dataset.project_boxes` against the devkit: the boxes `get_sample_data(token, box_vis_level)`
returns for camera, lidar and radar frames (keyframes and sweeps), in the sensor frame, and the same boxes in
the ego and global frames, for many frames at once."""

from __future__ import annotations

import os

import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.columns import to_numpy

os.environ.setdefault("MPLBACKEND", "Agg")

from conftest import IRREGULAR_VERSION, SYNTH_VERSION

TOLERANCE_M = 1e-9  # boxes moved with the same quaternions as the devkit's: rounding only
TOLERANCE_Q = 1e-12


@pytest.fixture(scope="module", params=["synth", "irregular"])
def case(request, devkit):
    """(Dataset, the devkit's NuScenes) of the regular and the irregular synthetic sets (the irregular one has
    boxes 0.05-1.5 m in front of CAM_FRONT and gapped tracks)."""
    root, out, version = ((request.getfixturevalue("synth_root"), request.getfixturevalue("synth_out"), SYNTH_VERSION)
                          if request.param == "synth" else
                          (request.getfixturevalue("irregular_root"), request.getfixturevalue("irregular_out"),
                           IRREGULAR_VERSION))
    return nuparquet.open(out), devkit.NuScenes(version=version, dataroot=str(root), verbose=False)


def _frames(ds, n_per_channel: int = 6) -> list[str]:
    """Tokens of a few keyframes and sweeps of every channel of one scene, mixed in one list."""
    scene = ds.scene_names()[-1]
    rows = (ds.scan("frames").filter(pl.col("scene_name") == scene)
            .select("token", pl.col("channel").cast(pl.String), "is_key_frame").collect())
    picked = [g.filter(pl.col("is_key_frame")).head(n_per_channel // 2)["token"].to_list()
              + g.filter(~pl.col("is_key_frame")).head(n_per_channel // 2)["token"].to_list()
              for _, g in rows.group_by("channel", maintain_order=True)]
    return [t for tokens in picked for t in tokens]


@pytest.mark.parametrize("level", ["any", "all", "none"])
def test_boxes_in_the_sensor_frame_equal_devkit_get_sample_data_for_every_sensor(case, level):
    from nuscenes.utils.geometry_utils import BoxVisibility

    ds, nusc = case
    tokens = _frames(ds)
    ours = ds.boxes(tokens, visibility=level, at="sensor")
    assert ours["frame_token"].unique(maintain_order=True).to_list() == [
        t for t in tokens if t in set(ours["frame_token"].to_list())]  # frames in the order given
    checked = 0
    for token in tokens:
        _, boxes, _ = nusc.get_sample_data(token, box_vis_level=getattr(BoxVisibility, level.upper()))
        mine = ours.filter(pl.col("frame_token") == token)
        assert mine["annotation_token"].to_list() == [b.token for b in boxes], token  # the devkit's order
        if not boxes:
            continue
        np.testing.assert_allclose(to_numpy(mine["translation"], (3,)), [b.center for b in boxes], atol=TOLERANCE_M)
        np.testing.assert_allclose(to_numpy(mine["size"], (3,)), [b.wlh for b in boxes], atol=0)
        np.testing.assert_allclose(to_numpy(mine["rotation"], (4,)), [b.orientation.elements for b in boxes],
                                   atol=TOLERANCE_Q)
        assert mine["category_name"].to_list() == [b.name for b in boxes]
        checked += len(boxes)
    assert checked > 20


def test_boxes_in_the_ego_and_global_frames_are_the_devkits_boxes_moved_that_far(case):
    ds, nusc = case
    tokens = _frames(ds, 4)
    at_ego = ds.boxes(tokens, visibility="none", at="ego")
    at_global = ds.boxes(tokens, visibility="none", at="global")
    for token in tokens:
        boxes = nusc.get_boxes(token)
        pose = nusc.get("ego_pose", nusc.get("sample_data", token)["ego_pose_token"])
        mine_global = at_global.filter(pl.col("frame_token") == token)
        assert mine_global["annotation_token"].to_list() == [b.token for b in boxes]
        if not boxes:
            continue
        np.testing.assert_allclose(to_numpy(mine_global["translation"], (3,)), [b.center for b in boxes], atol=0)
        from pyquaternion import Quaternion

        for box in boxes:  # the devkit's own moves: translate(-t), rotate(q.inverse)
            box.translate(-np.array(pose["translation"]))
            box.rotate(Quaternion(pose["rotation"]).inverse)
        mine_ego = at_ego.filter(pl.col("frame_token") == token)
        np.testing.assert_allclose(to_numpy(mine_ego["translation"], (3,)), [b.center for b in boxes], atol=TOLERANCE_M)
        np.testing.assert_allclose(to_numpy(mine_ego["rotation"], (4,)), [b.orientation.elements for b in boxes],
                                   atol=TOLERANCE_Q)


def test_project_boxes_of_a_dataset_finds_its_annotations_and_samples_itself(case):
    from nuparquet.frames.projection import project_boxes

    ds, _ = case
    tokens = _frames(ds)
    frames = ds.frame_rows(tokens)
    mine = ds.project_boxes(tokens, visibility="any")
    explicit = project_boxes(frames, ds.annotations_in_file_order(), ds.scan("tables/sample"), visibility="any")
    assert len(mine) == len(explicit) > 0
    assert mine.to_polars().equals(explicit.to_polars())
    sensor = ds.boxes(tokens, visibility="any", at="sensor").filter(pl.col("frame_token").is_in(list(mine.frame_token)))
    assert sorted(zip(sensor["frame_token"], sensor["annotation_token"])) == sorted(
        zip(mine.frame_token.tolist(), mine.annotation_token.tolist()))  # the camera boxes both keep


def test_boxes_have_the_documented_column_types_and_frame_index_is_the_row_of_the_frame_asked_for(case):
    """`boxes_at`'s docstring: frame_index (u32, the row of `frames`), the tokens and names as strings, translation,
    size and rotation as fixed-size float64 arrays, interpolated as a boolean."""
    ds, _ = case
    tokens = _frames(ds)
    for at in ("sensor", "ego", "global"):
        ours = ds.boxes(tokens, visibility="none", at=at)
        assert dict(ours.schema) == {
            "frame_index": pl.UInt32, "frame_token": pl.String, "annotation_token": pl.String,
            "instance_token": pl.String, "category_name": pl.String, "translation": pl.Array(pl.Float64, 3),
            "size": pl.Array(pl.Float64, 3), "rotation": pl.Array(pl.Float64, 4), "interpolated": pl.Boolean}, at
        row_of = {token: i for i, token in enumerate(tokens)}
        assert ours["frame_index"].to_list() == [row_of[t] for t in ours["frame_token"].to_list()], at
