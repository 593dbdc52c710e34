"""A converted output in object storage, reached as users reach it: one `storage_options` dict in polars' vocabulary
serves the manifest and every scan. Against a local S3 server (moto's, on 127.0.0.1): open, a scan whose filter is
pushed into the Parquet scan, SQL, and a render reading its rows remotely (the images stay local, under the dataroot given)."""

from __future__ import annotations

import json

import polars as pl
import pytest

import nuparquet
from nuparquet.errors import FormatError

BUCKET = "nuparquet-test"


@pytest.fixture(scope="module")
def s3(synth_out):
    """(storage_options, URL of synth_out uploaded to a local S3 server)."""
    boto3 = pytest.importorskip("boto3")  # moto[server]'s own dependency: a test extra, never skipped in CI
    from moto.server import ThreadedMotoServer

    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    endpoint = f"http://{host}:{port}"
    client = boto3.client("s3", endpoint_url=endpoint, aws_access_key_id="testing",
                          aws_secret_access_key="testing", region_name="us-east-1")
    client.create_bucket(Bucket=BUCKET)
    for path in synth_out.rglob("*"):
        if path.is_file():
            client.upload_file(str(path), BUCKET, f"out/{path.relative_to(synth_out)}")
    options = {"aws_endpoint_url": endpoint, "aws_access_key_id": "testing", "aws_secret_access_key": "testing",
               "aws_region": "us-east-1", "aws_allow_http": "true"}
    yield options, f"s3://{BUCKET}/out"
    server.stop()


def test_open_reads_the_manifest_through_the_same_storage_options_as_the_scans(s3, synth_out):
    options, url = s3
    ds = nuparquet.open(url, storage_options=options)
    assert ds.is_remote and ds.root == url
    assert ds.manifest == json.loads((synth_out / "manifest.json").read_text())
    assert ds.scan("scenes").collect().equals(nuparquet.open(synth_out).scan("scenes").collect())


def test_a_remote_scan_pushes_its_filter_into_the_parquet_scan_and_sql_works(s3, synth_out):
    options, url = s3
    remote, local = nuparquet.open(url, storage_options=options), nuparquet.open(synth_out)
    scene = local.scene_names()[-1]
    query = remote.scan("annotations").filter(pl.col("scene_name") == scene).select("token", "category_name")
    plan = query.explain()  # the filter is part of the Parquet scan (row groups pruned by their statistics)
    scan = plan[plan.index("Parquet SCAN"):]
    assert f'SELECTION: col("scene_name") == "{scene}"' in scan and "PROJECT 3/" in scan  # token, category_name and the filtered column
    expected = local.scan("annotations").filter(pl.col("scene_name") == scene).select("token", "category_name")
    assert query.collect().equals(expected.collect()) and query.collect().height > 0
    counts = remote.sql("SELECT category_name, COUNT(*) AS n FROM annotations GROUP BY 1 ORDER BY 1")
    assert counts.equals(local.sql("SELECT category_name, COUNT(*) AS n FROM annotations GROUP BY 1 ORDER BY 1"))
    assert remote.scan("sample").collect().equals(local.scan("tables/sample").collect())


def test_render_reads_its_rows_from_object_storage_and_draws_the_same_video(s3, synth_out, tmp_path):
    options, url = s3
    local = nuparquet.open(synth_out)
    scene = local.scene_names()[0]
    here = nuparquet.render(local, scene, out=tmp_path / "local.mp4", scale=0.2)
    # the images from the dataroot given (an object-store output never reads the local one recorded at conversion)
    there = nuparquet.render(nuparquet.open(url, storage_options=options, dataroot=local.dataroot), scene,
                             out=tmp_path / "remote.mp4", scale=0.2)
    assert there.frames_written == here.frames_written > 0
    assert (tmp_path / "remote.mp4").read_bytes() == (tmp_path / "local.mp4").read_bytes()


def test_storage_options_that_do_not_reach_the_bucket_are_a_format_error_naming_the_manifest(s3):
    options, url = s3
    wrong = dict(options, aws_secret_access_key="not-the-key", aws_endpoint_url="http://127.0.0.1:9")
    with pytest.raises(FormatError, match="cannot read manifest.json"):
        nuparquet.open(url, storage_options=wrong)


@pytest.fixture(scope="module")
def s3_points(s3, synth_points_out):
    """(storage_options, URL) of a converted output with lidar and radar points (and lidarseg labels) in the bucket."""
    import boto3

    options, _ = s3
    client = boto3.client("s3", endpoint_url=options["aws_endpoint_url"], aws_access_key_id="testing",
                          aws_secret_access_key="testing", region_name="us-east-1")
    for path in synth_points_out.rglob("*"):
        if path.is_file():
            client.upload_file(str(path), BUCKET, f"points/{path.relative_to(synth_points_out)}")
    return options, f"s3://{BUCKET}/points"


def test_points_are_read_from_object_storage_through_the_same_storage_options(s3_points, synth_points_out):
    """`ds.points` and `ds.radar_points` of a remote output read the frames' row groups through the dataset's own
    storage options (they used to open local paths, and a caller took the refusal for "not converted" and read
    the local files instead): the same values as the local output, and a frame the dataset lacks is refused."""
    options, url = s3_points
    remote, local = nuparquet.open(url, storage_options=options), nuparquet.open(synth_points_out)
    lidar = local.scan("frames").filter(pl.col("channel").cast(pl.String) == "LIDAR_TOP").select("token") \
        .head(3).collect()["token"].to_list()
    import numpy as np

    np.testing.assert_array_equal(remote.points(lidar), local.points(lidar))
    assert remote.points(lidar[0], columns=["x", "lidarseg_label"]).equals(
        local.points(lidar[0], columns=["x", "lidarseg_label"]))
    radar = local.scan("frames").filter(pl.col("channel").cast(pl.String) == "RADAR_FRONT").select("token") \
        .head(2).collect()["token"].to_list()
    np.testing.assert_array_equal(remote.radar_points(radar), local.radar_points(radar))
    from nuparquet.frames.points import FramesNotConverted

    with pytest.raises(FramesNotConverted, match="no points for sample_data nope"):
        remote.points(["nope"])


def test_the_sensor_reader_of_a_remote_output_reads_converted_points_and_never_falls_back_to_local_files(
        s3_points, synth_points_out, tmp_path):
    """The one sensor reader: a remote output's converted frame comes from the bucket, with its labels, even with
    no dataroot at all; a frame neither converted nor present as a file is one InputError naming the file and the
    dataset."""
    from nuparquet.sensors.reader import MissingSensorData

    options, url = s3_points
    remote = nuparquet.open(url, storage_options=options, dataroot=tmp_path / "no-files-here")
    local = nuparquet.open(synth_points_out)
    row = local.scan("frames").filter(pl.col("channel").cast(pl.String) == "LIDAR_TOP").select("token", "filename") \
        .head(1).collect().row(0, named=True)
    points, labels = remote.sensors.lidar(row["token"], row["filename"], labels="lidarseg")
    expected, truth = local.sensors.lidar(row["token"], row["filename"], labels="lidarseg")
    import numpy as np

    np.testing.assert_array_equal(points, expected)
    np.testing.assert_array_equal(labels, truth)
    (tmp_path / "no-files-here").mkdir()
    with pytest.raises(MissingSensorData, match="missing point file: .*no-files-here/samples/LIDAR_TOP/gone.pcd.bin "
                                                "\\(the lidar points of sample_data gone, not in lidar_points/"):
        remote.sensors.lidar("gone", "samples/LIDAR_TOP/gone.pcd.bin")


def test_export_json_and_the_devkit_skin_read_a_remote_output(s3, synth_out, tmp_path):
    """`export_json` of an object-store output writes the same files as of the local one, and
    `nuparquet.devkit.NuScenes(parquet=URL, storage_options=...)` serves the same records (both read local folders
    only before)."""
    from nuparquet.devkit import NuScenes

    options, url = s3
    remote = nuparquet.open(url, storage_options=options)
    nuparquet.export_json(remote, tmp_path / "remote")
    nuparquet.export_json(synth_out, tmp_path / "local")
    local_files = sorted(p.relative_to(tmp_path / "local") for p in (tmp_path / "local").rglob("*") if p.is_file())
    assert local_files and local_files == sorted(p.relative_to(tmp_path / "remote")
                                                 for p in (tmp_path / "remote").rglob("*") if p.is_file())
    assert all((tmp_path / "remote" / f).read_bytes() == (tmp_path / "local" / f).read_bytes() for f in local_files)
    version = remote.version
    theirs = NuScenes(version, parquet=url, storage_options=options, verbose=False)
    ours = NuScenes(version, parquet=synth_out, verbose=False)
    assert theirs.sample[3] == ours.sample[3] and theirs.get("sample_annotation", ours.sample_annotation[5]["token"]) \
        == ours.sample_annotation[5]
