"""The dataset registry: the conversion builds what `registry.BUILDERS` lists, batch by batch or whole, writes
part files and row groups as each builder asks, and records in the manifest what it built, what it skipped
and why, the channels and the files it read."""

from __future__ import annotations

import json

import polars as pl
import pyarrow.parquet as pq
import pytest

import nuparquet.conversion.pipeline as convert_module
from conftest import SYNTH_VERSION
from nuparquet.conversion import convert, registry
from nuparquet.conversion.builder import Builder

# The opt-in sensor datasets, skipped unless --sensors asks for them.
NOT_REQUESTED = {"lidar_points": "not requested (--sensors lidar)", "radar_points": "not requested (--sensors radar)",
                 **{f"sensor_files/{m}": f"not requested (--embed {m})" for m in ("camera", "lidar", "radar")}}


def _per_scene_counts(ctx, batch):
    """Two datasets whose names come from the data: per batch, the sample count of each scene, and a copy."""
    counts = (batch.rows["sample"].group_by("scene_token").len()
              .join(ctx.tables["scene"].select(pl.col("token").alias("scene_token"), pl.col("name").alias("scene_name")),
                    on="scene_token").sort("scene_name"))
    return {"extra/counts": counts, "extra/batches": counts.with_columns(batch=pl.lit(batch.index))}


def _never(ctx):
    return "not requested"


@pytest.fixture
def with_test_builders(monkeypatch):
    extra = (
        Builder("extra", _per_scene_counts, parts="per_batch"),
        Builder("optional", lambda ctx, batch: pl.DataFrame({"x": [1]}), wanted=_never),
        Builder("after-optional", lambda ctx: pl.DataFrame({"x": [1]}), scope="whole", needs=("optional",)),
        Builder("summary", lambda ctx: ctx.dataset("extra/counts").select(pl.col("len").sum()).collect(),
                scope="whole", group_by=None, needs=("extra",)),
    )
    monkeypatch.setattr(convert_module, "BUILDERS", registry.BUILDERS + extra)


def test_builders_write_part_files_per_batch_and_manifest_lists_built_and_skipped(synth_root, tmp_path,
                                                                                with_test_builders):
    out = tmp_path / "out"
    manifest = convert(synth_root, SYNTH_VERSION, out, scenes_per_batch=1)
    samples = json.loads((synth_root / SYNTH_VERSION / "sample.json").read_text())
    scenes = json.loads((synth_root / SYNTH_VERSION / "scene.json").read_text())
    # one part per batch (= per scene here), every scene present once with its sample count
    parts = sorted(p.name for p in (out / "extra/counts").glob("*.parquet"))
    assert parts == [f"part-{i:05d}.parquet" for i in range(len(scenes))]
    counts = pl.read_parquet(out / "extra/counts").sort("scene_name")
    expected = {s["name"]: sum(x["scene_token"] == s["token"] for x in samples) for s in scenes}
    assert dict(zip(counts["scene_name"], counts["len"])) == expected
    assert sorted(pl.read_parquet(out / "extra/batches")["batch"].to_list()) == list(range(len(scenes)))
    assert manifest["datasets"]["extra/counts"]["parts"] == len(scenes)
    assert manifest["datasets"]["extra/counts"]["rows"] == len(scenes)
    # a whole builder reads what a scenes builder wrote
    assert pl.read_parquet(out / "summary")["len"].to_list() == [len(samples)]
    # skipped, with the reason, and what needs it skipped too
    assert manifest["skipped"] == {"optional": "not requested", "after-optional": "needs optional, not built", **NOT_REQUESTED}
    assert not (out / "optional").exists() and not (out / "after-optional").exists()
    assert json.loads((out / "manifest.json").read_text())["skipped"] == manifest["skipped"]


def test_batch_size_does_not_change_the_datasets(synth_root, synth_out, tmp_path):
    """Scenes built one per batch give the same rows as the default batches (no scene dropped or repeated at a
    batch edge, the last batch included)."""
    convert(synth_root, SYNTH_VERSION, tmp_path / "one", scenes_per_batch=1)
    for name in ("frames", "annotations", "scenes", "instances"):
        a = pl.read_parquet(synth_out / name)
        b = pl.read_parquet(tmp_path / "one" / name)
        assert a.equals(b), name


def test_row_groups_follow_scenes(synth_out):
    """A one-scene filter reads only that scene's row groups: each row group holds exactly one scene."""
    for name in ("frames", "annotations"):
        for path in (synth_out / name).glob("*.parquet"):
            meta = pq.ParquetFile(path).metadata
            column = [meta.row_group(0).column(i).path_in_schema for i in range(meta.num_columns)].index("scene_name")
            stats = [meta.row_group(g).column(column).statistics for g in range(meta.num_row_groups)]
            assert all(s.min == s.max for s in stats), name
            assert len({s.min for s in stats}) == meta.num_row_groups, name


def test_manifest_records_channels_and_the_files_read(synth_root, synth_out):
    manifest = json.loads((synth_out / "manifest.json").read_text())
    sensors = json.loads((synth_root / SYNTH_VERSION / "sensor.json").read_text())
    channels = manifest["channels"]
    assert channels["reference_lidar"] == "LIDAR_TOP"
    assert sorted(channels["cameras"]) == sorted(s["channel"] for s in sensors if s["modality"] == "camera")
    assert sorted(channels["radars"]) == sorted(s["channel"] for s in sensors if s["modality"] == "radar")
    assert channels["camera_layout"] == [["CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT"],
                                         ["CAM_BACK_LEFT", "CAM_BACK", "CAM_BACK_RIGHT"]]
    tables = {f["path"] for f in manifest["files"] if f["kind"] == "table"}
    assert tables == {f"{SYNTH_VERSION}/{p.name}" for p in (synth_root / SYNTH_VERSION).glob("*.json")}
    can_bus = {f["path"] for f in manifest["files"] if f["kind"].startswith("can_bus")}
    assert can_bus == {f"can_bus/{p.name}" for p in (synth_root / "can_bus").glob("*.json")}
    maps = {f["path"] for f in manifest["files"] if f["kind"] == "map_expansion"}
    assert maps == {f"maps/expansion/{p.name}" for p in (synth_root / "maps" / "expansion").glob("*.json")}
    assert len(manifest["files"]) == len(tables) + len(can_bus) + len(maps)
    assert manifest["skipped"] == NOT_REQUESTED  # sensor points are opt-in (--sensors)


def test_manifest_channels_of_a_seven_camera_rig(lyft_rig_out):
    channels = json.loads((lyft_rig_out / "manifest.json").read_text())["channels"]
    assert len(channels["cameras"]) == 7 and "CAM_FRONT_ZOOMED" in channels["cameras"]
    assert sorted(channels["lidars"]) == ["LIDAR_FRONT_LEFT", "LIDAR_FRONT_RIGHT", "LIDAR_TOP"]
    assert sorted(sum(channels["camera_layout"], [])) == sorted(channels["cameras"])


@pytest.mark.parametrize("options, message", [({"scenes_per_batch": 0}, "at least 1"), ({"version": " "}, "--version")])
def test_bad_options_are_usage_errors(synth_root, tmp_path, options, message):
    from nuparquet.errors import UsageError

    version = options.pop("version", SYNTH_VERSION)
    with pytest.raises(UsageError, match=message):
        convert(synth_root, version, tmp_path / "out", **options)
    assert not (tmp_path / "out").exists()


def test_every_builder_names_a_dataset_schema_that_describes_what_it_writes(synth_root, tmp_path):
    """A builder's `schema` is the one place its dataset's columns are declared (schemas/): it must name a schema
    that exists, and the schema's declared columns must be the written dataset's (a typo in the name of a builder
    that writes its own part files would otherwise go unnoticed)."""
    from nuparquet.conversion.formats import FORMATS
    from nuparquet.schemas import dataset_schemas, schema_for

    known = dataset_schemas()
    builders = {b.name: b for b in registry.BUILDERS}
    for fmt in FORMATS:
        builders.update({b.name: b for b in fmt.builders})
    for name, builder in builders.items():
        assert builder.schema is None or builder.schema in known, (name, builder.schema)
    out = tmp_path / "out"
    manifest = convert(synth_root, SYNTH_VERSION, out, embed=("camera", "lidar", "radar"), sensors=("lidar",))
    for name in manifest["datasets"]:
        if name in builders and builders[name].schema:
            declared = schema_for(name)
            written = pq.read_schema(next((out / name).glob("*.parquet"))).names
            assert declared is not None and declared.name == builders[name].schema, name
            assert set(declared.names) <= set(written), name
