"""Sensor files inside the dataset (`convert --embed camera,lidar,radar`): the embedded bytes are the files, and an
output whose dataroot is gone serves the one sensor reader, the training loader, a picture and the MCAP export
exactly as the files do, from a folder or from a local S3 server (moto's, as tests/dataset/test_object_store.py);
what is not embedded is refused naming it and the flag."""

from __future__ import annotations

import json
import re

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest

import nuparquet
from nuparquet.conversion.builders.sensor_files import ROW_GROUP_BYTES
from nuparquet.errors import UsageError
from nuparquet.sensors.reader import MissingSensorData
from tests.conftest import EXTRACT_VERSION, SYNTH_VERSION, converted

MODALITIES = ("camera", "lidar", "radar")
BUCKET = "nuparquet-embedded"


@pytest.fixture(scope="module")
def embed_out(synth_root, tmp_path_factory):
    return converted(tmp_path_factory, "synth-embed-out", synth_root, SYNTH_VERSION, embed=MODALITIES)


@pytest.fixture(scope="module")
def camera_out(synth_root, tmp_path_factory):
    return converted(tmp_path_factory, "synth-embed-camera", synth_root, SYNTH_VERSION, embed="camera")


@pytest.fixture()
def no_root(tmp_path):
    """A dataroot that does not exist: whatever is read must come from the output."""
    return tmp_path / "no-dataroot-here"


def _frames(ds, modality: str) -> pl.DataFrame:
    return (ds.scan("frames").filter(pl.col("modality").cast(pl.String) == modality)
            .select("token", "filename", pl.col("scene_name").cast(pl.String)).sort("token").collect())


def test_embedded_files_are_the_files_byte_for_byte_one_part_per_scene(embed_out, synth_root):
    ds = nuparquet.open(embed_out)
    manifest = json.loads((embed_out / "manifest.json").read_text())
    for modality in MODALITIES:
        name = f"sensor_files/{modality}"
        frames = _frames(ds, modality)
        stored = ds.scan(name).select("sample_data_token", "filename", "scene_name", "bytes").collect()
        assert stored.height == frames.height == manifest["datasets"][name]["rows"] > 0, modality
        # every frame once, keyframes and sweeps, under its own filename and scene
        assert stored.select("sample_data_token", "filename", pl.col("scene_name").cast(pl.String)).sort(
            "sample_data_token").rename({"sample_data_token": "token"}).equals(frames)
        for filename, data in zip(stored["filename"].to_list(), stored["bytes"].to_list()):
            assert data == (synth_root / filename).read_bytes(), filename
        parts = manifest["datasets"][name]["scene_parts"]
        assert sorted(parts) == sorted(set(frames["scene_name"])) and len(set(parts.values())) == len(parts)
        for scene, part in parts.items():
            file = pq.ParquetFile(embed_out / name / part)
            assert set(file.read(columns=["scene_name"]).column(0).to_pylist()) == {scene}
            for g in range(file.metadata.num_row_groups):  # whole files, at most ~1 MiB unless one file is larger
                group = file.read_row_group(g, columns=["bytes"]).column(0).to_pylist()
                assert len(group) == 1 or sum(map(len, group)) <= ROW_GROUP_BYTES
        assert manifest["datasets"][name]["missing_count"] == 0
        entry = manifest["datasets"][name]  # the manifest's size is the part files' on disk
        assert entry["bytes"] == sum(p.stat().st_size for p in (embed_out / name).glob("*.parquet")) > 0
        assert entry["parts"] == len(parts)
        embedded = ds.sensors.embedded(modality)
        assert frames["token"][0] in embedded and frames["token"][-1] in embedded and "f" * 32 not in embedded
    assert ds.sensors.embedded("camera") is not None and "sensor_files/camera" in ds.datasets
    # the camera's groups hold several images (so the packing is exercised), the lidar's one file each
    camera = pq.ParquetFile(next((embed_out / "sensor_files/camera").glob("*.parquet"))).metadata
    assert max(camera.row_group(g).num_rows for g in range(camera.num_row_groups)) > 1


def test_the_sensor_reader_without_a_dataroot_gives_what_the_files_give(embed_out, synth_out, synth_root, no_root):
    """`synth_out` is the same dataroot converted without --embed: its reader reads the files."""
    embedded = nuparquet.open(embed_out, dataroot=no_root)
    files = nuparquet.open(synth_out, dataroot=synth_root)
    for modality in MODALITIES:
        frames = _frames(files, modality)
        for token, filename in zip(frames["token"].to_list()[:5], frames["filename"].to_list()[:5]):
            assert embedded.sensors.file_bytes(token, filename, modality) == (synth_root / filename).read_bytes()
            assert embedded.sensors.file_size(token, filename, modality) == (synth_root / filename).stat().st_size
            if modality != "camera":
                assert embedded.sensors.points(token, filename, modality).equals(
                    files.sensors.points(token, filename, modality))
    lidar = _frames(files, "lidar").row(0, named=True)
    points, _ = embedded.sensors.lidar(lidar["token"], lidar["filename"])
    raw = np.fromfile(synth_root / lidar["filename"], dtype=np.float32).reshape(-1, 5)
    np.testing.assert_array_equal(points, raw[:, :4])


def test_the_real_extract_s_images_are_embedded_byte_for_byte_and_serve_the_loader(extract_root, tmp_path_factory,
                                                                                    no_root):
    """Real JPEGs (the extract holds its keyframes' files, not its sweeps'): each present file embedded as it is,
    each absent one listed, and a training item's images decoded from the output equal cv2.imread of the files."""
    import cv2

    from nuparquet.training import Samples

    out = converted(tmp_path_factory, "extract-embed-camera", extract_root, EXTRACT_VERSION, embed="camera")
    ds = nuparquet.open(out, dataroot=no_root)
    frames = _frames(ds, "camera")
    present = [name for name in frames["filename"].to_list() if (extract_root / name).is_file()]
    entry = ds.manifest["datasets"]["sensor_files/camera"]
    assert entry["rows"] == len(present) > 400 and entry["missing_count"] == frames.height - len(present) > 0
    stored = ds.scan("sensor_files/camera").select("filename", "bytes").collect()
    assert sorted(stored["filename"].to_list()) == sorted(present)
    for name, data in stored.iter_rows():
        assert data == (extract_root / name).read_bytes(), name
    samples = Samples(ds, "val", version="v1.0-mini", lidar=False, boxes=False, sweeps=0)
    item = samples[len(samples) - 1]
    tokens = [t.decode() for t in samples._cam_token[samples.indices[-1]]]
    names = dict(ds.scan("frames").filter(pl.col("token").is_in(tokens)).select("token", "filename").collect().rows())
    for image, token in zip(item["img"], tokens):
        np.testing.assert_array_equal(image, cv2.imread(str(extract_root / names[token]), cv2.IMREAD_COLOR))


def _same_items(a, b) -> None:
    assert len(a) == len(b) > 0
    for i in range(len(a)):
        x, y = a[i], b[i]
        assert x.keys() == y.keys()
        for key in x:
            if isinstance(x[key], np.ndarray):
                np.testing.assert_array_equal(x[key], y[key], err_msg=key)
            else:
                assert x[key] == y[key], key


def test_a_training_sample_without_a_dataroot_equals_the_one_read_from_files(embed_out, synth_out, synth_root,
                                                                            no_root):
    from nuparquet.training import Samples

    embedded = Samples(nuparquet.open(embed_out, dataroot=no_root), "train", sweeps=2, version="v1.0-trainval")
    files = Samples(nuparquet.open(synth_out, dataroot=synth_root), "train", sweeps=2, version="v1.0-trainval")
    item = embedded[3]  # a sample with previous sweeps
    assert item["img"].shape[0] == 6 and item["lidar_sweeps"] == 2 and item["points"].shape[0] > 0
    import cv2

    token = embedded._cam_token[embedded.indices[3]][0].decode()
    first = embedded.dataset.scan("frames").filter(pl.col("token") == token).select("filename").collect().item()
    np.testing.assert_array_equal(item["img"][0], cv2.imread(str(synth_root / first), cv2.IMREAD_COLOR))
    _same_items(embedded, files)


def test_pictures_a_video_and_an_mcap_export_without_a_dataroot_equal_those_from_files(embed_out, synth_out, synth_root,
                                                                                 no_root, tmp_path):
    from nuparquet.mcap.export import export_mcap
    from nuparquet.rendering.pictures.sample_data import render_sample_data

    embedded, files = nuparquet.open(embed_out, dataroot=no_root), nuparquet.open(synth_out, dataroot=synth_root)
    for modality in ("camera", "lidar", "radar"):
        token = _frames(files, modality)["token"][0]
        np.testing.assert_array_equal(render_sample_data(embedded, token, nsweeps=2),
                                      render_sample_data(files, token, nsweeps=2))
    scene = files.scene_names()[0]
    for name, ds in (("files", files), ("embedded", embedded)):  # a scene video, lidar points drawn on the images
        nuparquet.render(ds, scene, out=tmp_path / f"{name}.mp4", scale=0.2, lidar=True)
    assert (tmp_path / "embedded.mp4").read_bytes() == (tmp_path / "files.mp4").read_bytes()
    here = export_mcap(files, scene, tmp_path / "files.mcap")
    there = export_mcap(embedded, scene, tmp_path / "embedded.mcap")
    assert there.sensor_bytes == here.sensor_bytes > 0 and not there.missing
    assert (tmp_path / "embedded.mcap").read_bytes() == (tmp_path / "files.mcap").read_bytes()


def test_a_report_without_a_dataroot_has_the_videos_and_stills_of_the_files(embed_out, synth_out, synth_root,
                                                                               no_root, tmp_path):
    """`nuparquet report` of an output embedding its sensors needs no dataroot: its scene video and keyframe
    renderings are byte for byte those of the same scene read from the files."""
    from nuparquet.engine import EngineOptions
    from nuparquet.site import build_report

    files, embedded = nuparquet.open(synth_out, dataroot=synth_root), nuparquet.open(embed_out, dataroot=no_root)
    scene = files.scene_names()[0]
    written = {}
    for name, ds in (("files", files), ("embedded", embedded)):
        result = build_report(ds, None, tmp_path / name, engine=EngineOptions(engine="serial"), scenes=(scene,),
                              stills=1)
        assert result.videos[scene] is not None and not result.problems, (name, result.problems)
        written[name] = sorted(p.relative_to(tmp_path / name) for p in (tmp_path / name).rglob("*")
                               if p.suffix in (".mp4", ".jpg"))
    assert written["files"] == written["embedded"] and any(p.suffix == ".mp4" for p in written["files"])
    for relative in written["files"]:
        assert (tmp_path / "embedded" / relative).read_bytes() == (tmp_path / "files" / relative).read_bytes(), relative


def test_threads_reading_a_fresh_output_at_once_get_each_file(embed_out, synth_root, no_root):
    """Eight threads asking a just-opened output for files at the same moment (the report's video and stills do) get
    each file's bytes: the part files are read under one lock, the index's first build included."""
    import threading

    from nuparquet.sensors.embedded import EmbeddedFiles

    files = _frames(nuparquet.open(embed_out, dataroot=no_root), "camera").head(16)
    for attempt in range(5):
        embedded = EmbeddedFiles(nuparquet.open(embed_out, dataroot=no_root), "camera")
        barrier, got, errors = threading.Barrier(8), {}, []

        def read(rows):
            barrier.wait()
            try:
                for token in rows:
                    got[token] = embedded.read(token)
            except Exception as exc:  # the race showed as pyarrow's "ReadRangeCache did not find ..."
                errors.append(exc)

        threads = [threading.Thread(target=read, args=(files["token"].to_list()[i::8],)) for i in range(8)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert errors == [], (attempt, errors[:1])
        for token, filename in zip(files["token"], files["filename"]):
            assert got[token] == (synth_root / filename).read_bytes()


def test_an_output_embedding_only_its_camera_says_the_points_are_missing(camera_out, no_root):
    from nuparquet.training import Samples

    ds = nuparquet.open(camera_out, dataroot=no_root)
    assert [n for n in ds.datasets if n.startswith("sensor_files/")] == ["sensor_files/camera"]
    assert ds.manifest["skipped"]["sensor_files/lidar"] == "not requested (--embed lidar)"
    images = Samples(ds, "train", lidar=False, sweeps=0, version="v1.0-trainval")
    assert images[0]["img"].shape[0] == 6  # the images need no dataroot
    samples = Samples(ds, "train", sweeps=0, version="v1.0-trainval")
    with pytest.raises(UsageError, match="^the dataroot .*no-dataroot-here \\(where the lidar points \\(of sample_data "
                                         ".*\\) are read from\\) does not exist; .*; or convert with --embed lidar to "
                                         "store them in the output \\(it embeds camera\\)$"):
        samples[0]
    (no_root / "samples").mkdir(parents=True)  # a dataroot without the file: the frame is missing, and why
    with pytest.raises(MissingSensorData, match="missing point file: .*no-dataroot-here/samples/LIDAR_TOP/.* "
                                                "\\(the lidar points of sample_data .*, not converted: convert "
                                                "--sensors lidar, not embedded: convert --embed lidar; "):
        samples[0]


@pytest.fixture(scope="module")
def gapped(synth_root, synth_out, tmp_path_factory):
    """(dataroot, output, {modality: (token, filename)}, progress events): `synth_root` linked file by file, its
    first camera image, its last lidar sweep and every radar file deleted, converted with --embed camera,lidar,radar."""
    import os
    import shutil

    root = tmp_path_factory.mktemp("gapped") / "data"
    shutil.copytree(synth_root, root, copy_function=os.link)
    ds = nuparquet.open(synth_out)  # the same records
    frames = {}
    for modality, pick in (("camera", 0), ("lidar", -1), ("radar", 0)):
        rows = ds.scan("frames").filter(pl.col("modality").cast(pl.String) == modality).sort("filename").collect()
        frames[modality] = (rows["token"][pick], rows["filename"][pick])
        for name in (rows["filename"] if modality == "radar" else [frames[modality][1]]):
            (root / name).unlink()
    events = []
    out = root.parent / "out"
    nuparquet.convert(root, SYNTH_VERSION, out, embed=MODALITIES, on_progress=events.append)
    return root, out, frames, events


def test_a_file_missing_at_conversion_is_listed_and_read_from_the_dataroot_when_there(gapped, synth_root, no_root):
    root, out, frames, _ = gapped
    manifest = json.loads((out / "manifest.json").read_text())
    for modality, (token, filename) in frames.items():
        entry = manifest["datasets"][f"sensor_files/{modality}"]
        every = _frames(nuparquet.open(out), modality).height
        missing = every if modality == "radar" else 1  # radar: every file gone, an empty dataset
        assert entry["missing_count"] == missing and filename in entry["missing_files"]
        assert entry["rows"] == entry["frames"] == every - missing
        assert nuparquet.open(out).scan(f"sensor_files/{modality}").collect().height == every - missing
        assert not nuparquet.open(out).scan(f"sensor_files/{modality}").filter(
            pl.col("sample_data_token") == token).collect().height
        with pytest.raises(MissingSensorData, match=f"^missing (image|point) file: {re.escape(filename)} \\(the "
                                                    f"{modality} .* of sample_data {token}: not in "
                                                    f"sensor_files/{modality}/, its file was missing at conversion; "
                                                    "and no dataroot"):
            nuparquet.open(out, dataroot=no_root).sensors.file_bytes(token, filename, modality)
        # the file back under a dataroot given: read from there
        assert nuparquet.open(out, dataroot=synth_root).sensors.file_bytes(token, filename, modality) == \
            (synth_root / filename).read_bytes()
        # a dataroot that lacks it too: the message says it is not in the embedded files either
        with pytest.raises(MissingSensorData, match=f"^missing (image|point) file: .*{re.escape(filename)} .*not in "
                                                    f"sensor_files/{modality}/; or --dataroot PATH"):
            nuparquet.open(out, dataroot=root).sensors.file_bytes(token, filename, modality)
    assert any("sensor_files/camera: 1 sensor file(s) missing, not embedded" in w for w in manifest["warnings"])
    from nuparquet.conversion import convert
    from nuparquet.problems import ProblemsFound

    with pytest.raises(ProblemsFound, match="sensor file missing \\(--strict\\)"):
        convert(root, SYNTH_VERSION, out.parent / "strict", embed="camera", strict=True)


def test_the_progress_total_counts_a_unit_per_scene_of_each_embedded_modality(gapped):
    """Set once, never grown, reached: one unit per builder and one per scene it embeds (two scenes)."""
    events = gapped[3]
    totals = {e.total for e in events if e.total is not None}
    assert len(totals) == 1 and events[-1].finished and events[-1].done == events[-1].total == totals.pop()
    steps = [e.step for e in events if e.step]
    for modality in MODALITIES:
        assert sum(s.startswith(f"sensor_files/{modality} scene-") for s in steps) == 2, modality


def test_the_bytes_are_stored_uncompressed_the_names_dictionary_encoded(embed_out):
    """A read of one file is a copy out of its column chunk (JPEG and float32 points barely compress); the scene and
    channel names are dictionaries, the other columns zstd."""
    for modality in MODALITIES:
        meta = pq.ParquetFile(next((embed_out / f"sensor_files/{modality}").glob("*.parquet"))).metadata
        names = meta.schema.to_arrow_schema().names
        for g in range(meta.num_row_groups):
            column = {name: meta.row_group(g).column(i) for i, name in enumerate(names)}
            assert column["bytes"].compression == "UNCOMPRESSED"
            assert not any("DICTIONARY" in e for e in column["bytes"].encodings)
            assert column["sample_data_token"].compression == column["filename"].compression == "ZSTD"
            assert all(any("DICTIONARY" in e for e in column[c].encodings) for c in ("scene_name", "channel"))


def test_embed_refuses_an_unknown_modality(synth_root, tmp_path, capsys):
    from nuparquet.cli.main import main
    from nuparquet.conversion.options import ConvertOptions

    with pytest.raises(UsageError, match="^--embed takes camera, lidar, radar \\(got sonar\\)$"):
        ConvertOptions(embed="camera,sonar")
    assert ConvertOptions(embed=" Camera,lidar,camera").embed == ("camera", "lidar")
    assert main(["convert", str(synth_root), "--version", SYNTH_VERSION, "--out", str(tmp_path / "o"),
                 "--embed", "lidar,sonar"]) != 0
    assert "--embed takes camera, lidar, radar (got sonar)" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# -- object storage ---------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def s3(embed_out, camera_out, synth_out):
    """(storage_options, {name: URL}) of the embedded, camera-only and plain outputs in a local S3 bucket."""
    boto3 = pytest.importorskip("boto3")  # moto[server]'s own dependency: a test extra, never skipped in CI
    from moto.server import ThreadedMotoServer

    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    endpoint = f"http://{host}:{port}"
    client = boto3.client("s3", endpoint_url=endpoint, aws_access_key_id="testing",
                          aws_secret_access_key="testing", region_name="us-east-1")
    client.create_bucket(Bucket=BUCKET)
    urls = {}
    for name, out in (("embedded", embed_out), ("camera", camera_out), ("plain", synth_out)):
        for path in out.rglob("*"):
            if path.is_file():
                client.upload_file(str(path), BUCKET, f"{name}/{path.relative_to(out)}")
        urls[name] = f"s3://{BUCKET}/{name}"
    options = {"aws_endpoint_url": endpoint, "aws_access_key_id": "testing", "aws_secret_access_key": "testing",
               "aws_region": "us-east-1", "aws_allow_http": "true"}
    yield options, urls
    server.stop()


def test_a_local_s3_serves_a_whole_training_epoch_without_a_dataroot(s3, embed_out, synth_root):
    from nuparquet.training import Samples

    options, urls = s3
    remote = nuparquet.open(urls["embedded"], storage_options=options)
    assert remote.dataroot == str(synth_root.resolve())  # recorded, and never read: the files come from the bucket
    _same_items(Samples(remote, "train", sweeps=2, version="v1.0-trainval"),
                Samples(nuparquet.open(embed_out, dataroot=synth_root), "train", sweeps=2, version="v1.0-trainval"))


def test_an_object_store_output_without_embedded_sensors_is_refused_naming_the_flag(s3):
    from nuparquet.training import Samples

    options, urls = s3
    plain = Samples(nuparquet.open(urls["plain"], storage_options=options), "train", sweeps=0,
                    version="v1.0-trainval")
    with pytest.raises(UsageError, match=f"^{urls['plain']} is on object storage and does not hold the lidar points "
                                         "\\(of sample_data .*\\) \\(it embeds no sensor files\\): convert with "
                                         "--embed camera,lidar,radar \\(those needed\\) .*or give the local dataroot: "
                                         "--dataroot PATH \\(in Python nuparquet.open\\(URL, storage_options=\\.\\.\\., "
                                         "dataroot=\\.\\.\\.\\)\\)$"):
        plain[0]
    camera = Samples(nuparquet.open(urls["camera"], storage_options=options), "train", sweeps=0,
                     version="v1.0-trainval")
    with pytest.raises(UsageError, match="does not hold the lidar points .*\\(it embeds camera\\): convert with "
                                         "--embed"):
        camera[0]
    images = Samples(nuparquet.open(urls["camera"], storage_options=options), "train", lidar=False, sweeps=0,
                     version="v1.0-trainval")
    assert images[0]["img"].shape[0] == 6


def test_embedding_a_modality_the_rig_lacks_writes_an_empty_scannable_dataset(lyft_rig_root, tmp_path):
    """--embed radar of a rig without radar (Lyft's): sensor_files/radar/ holds one empty part of the declared
    schema, scans to no row, and the reader says no radar file is embedded."""
    from tests.conftest import LYFT_RIG_VERSION

    out = tmp_path / "out"
    nuparquet.convert(lyft_rig_root, LYFT_RIG_VERSION, out, embed=("radar",))
    ds = nuparquet.open(out, dataroot=tmp_path / "no-dataroot-here")
    parts = sorted(p.name for p in (out / "sensor_files" / "radar").iterdir())
    assert parts == ["part-00000.parquet"]
    frame = ds.scan("sensor_files/radar").collect()
    assert frame.height == 0 and {"sample_data_token", "bytes"} <= set(frame.columns)
    manifest = json.loads((out / "manifest.json").read_text())["datasets"]["sensor_files/radar"]
    assert manifest["frames"] == 0 and manifest["scene_parts"] == {}
