"""`nuparquet.open`: manifest checks, lazy scans of every dataset, SQL names, and reading only what a
one-scene query needs."""

from __future__ import annotations

import json
import re
import shutil

import polars as pl
import pyarrow.parquet as pq
import pytest

import nuparquet
from nuparquet import queries
from nuparquet.cli.main import main
from nuparquet.dataset import Dataset
from nuparquet.errors import QueryError
from nuparquet.errors import FormatError, UsageError
from nuparquet.schemas import FORMAT_VERSION

DERIVED = ("frames", "annotations", "scenes", "instances")


def test_open_reads_the_manifest_and_lists_every_dataset(extract_out, extract_root):
    ds = nuparquet.open(extract_out)
    manifest = json.loads((extract_out / "manifest.json").read_text())
    assert isinstance(ds, Dataset) and ds.manifest == manifest
    assert ds.datasets == list(manifest["datasets"])
    assert set(DERIVED) <= set(ds.datasets) and "tables/sample" in ds.datasets
    assert ds.root == str(extract_out.resolve())
    assert ds.dataroot == manifest["source"]["dataroot"] and ds.version == manifest["source"]["version"]
    assert nuparquet.open(str(extract_out)).datasets == ds.datasets  # str or Path


def test_scan_of_every_dataset_is_lazy_and_has_the_manifest_row_count(extract_out):
    ds = nuparquet.open(extract_out)
    for name in ds.datasets:
        lf = ds.scan(name)
        assert isinstance(lf, pl.LazyFrame)
        assert lf.select(pl.len()).collect().item() == ds.manifest["datasets"][name]["rows"], name


def test_scan_columns_are_those_of_the_schema_files(extract_out):
    from nuparquet.schemas import dataset_schemas, table_schemas

    ds = nuparquet.open(extract_out)
    for name in DERIVED:
        assert ds.scan(name).collect_schema().names() == dataset_schemas()[name].names
    assert ds.scan("tables/sample").collect_schema().names() == table_schemas()["sample"].names


def test_nothing_is_read_until_collect(extract_out, tmp_path):
    copy = tmp_path / "out"
    shutil.copytree(extract_out, copy)
    ds = nuparquet.open(copy)
    for path in (copy / "annotations").rglob("*.parquet"):
        path.write_bytes(b"not parquet")  # any read of the data now fails
    lazy = queries.class_distribution(ds.scan("annotations").filter(pl.col("scene_name") == "x"))
    assert isinstance(lazy, pl.LazyFrame)
    with pytest.raises(pl.exceptions.PolarsError):
        lazy.collect()


def test_scan_of_an_unknown_name_lists_the_valid_names(extract_out):
    with pytest.raises(UsageError, match=r"no dataset 'annotation'.*annotations.*tables/sample"):
        nuparquet.open(extract_out).scan("annotation")


# --- what open refuses ------------------------------------------------------------------------------------------

def _with_manifest(tmp_path, extract_out, **changes):
    manifest = json.loads((extract_out / "manifest.json").read_text())
    manifest.update(changes)
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out


def test_open_a_missing_directory_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="no such directory"):
        nuparquet.open(tmp_path / "nope")


def test_open_a_directory_without_manifest_says_it_is_not_a_nuparquet_output(tmp_path):
    (tmp_path / "sample.json").write_text("[]")
    with pytest.raises(FormatError, match="not a nuparquet output"):
        nuparquet.open(tmp_path)


def test_open_a_file_is_a_format_error(tmp_path):
    (tmp_path / "f.parquet").write_bytes(b"x")
    with pytest.raises(FormatError, match="not a directory"):
        nuparquet.open(tmp_path / "f.parquet")


def test_open_a_manifest_of_another_format_is_a_format_error(tmp_path, extract_out):
    with pytest.raises(FormatError, match="not a nuparquet output"):
        nuparquet.open(_with_manifest(tmp_path, extract_out, format="something-else"))


def test_open_a_newer_format_version_asks_to_upgrade(tmp_path, extract_out):
    with pytest.raises(FormatError, match=rf"format {FORMAT_VERSION + 1}, newer.*upgrade"):
        nuparquet.open(_with_manifest(tmp_path, extract_out, format_version=FORMAT_VERSION + 1))


def test_open_an_older_format_version_asks_to_convert_again(tmp_path, extract_out):
    with pytest.raises(FormatError, match=rf"format {FORMAT_VERSION - 1}, older.*convert"):
        nuparquet.open(_with_manifest(tmp_path, extract_out, format_version=FORMAT_VERSION - 1))


def test_an_older_format_version_is_refused_naming_the_output_both_versions_and_the_fix(tmp_path, synth_out):
    """The synthetic conversion (the mutation runs leave out tests of the real extract): the message starts with the
    directory as opened, then says which format it holds, which one this nuparquet reads, and the command to run."""
    out = _with_manifest(tmp_path, synth_out, format_version=FORMAT_VERSION - 1)
    with pytest.raises(FormatError) as error:
        nuparquet.open(out)
    message = str(error.value)
    assert message.startswith(f"{out.resolve()}: written in nuparquet format {FORMAT_VERSION - 1}, older ")
    assert f"({FORMAT_VERSION})" in message and message.endswith("`nuparquet convert --overwrite`")


def test_a_newer_format_version_is_refused_naming_the_output_both_versions_and_the_fix(tmp_path, synth_out):
    """The synthetic conversion (the mutation runs leave out tests of the real extract): the message starts with the
    directory as opened, says which format it holds, which one this nuparquet reads, and to upgrade."""
    out = _with_manifest(tmp_path, synth_out, format_version=FORMAT_VERSION + 1)
    with pytest.raises(FormatError) as error:
        nuparquet.open(out)
    assert str(error.value) == (f"{out.resolve()}: written in nuparquet format {FORMAT_VERSION + 1}, newer than this "
                                f"nuparquet reads ({FORMAT_VERSION}); upgrade nuparquet")


def test_open_takes_a_file_url_of_a_local_directory(synth_out):
    ds = nuparquet.open(f"file://{synth_out}")
    assert not ds.is_remote and ds.root == str(synth_out.resolve())
    assert ds.manifest == json.loads((synth_out / "manifest.json").read_text())
    assert ds.scan("scenes").collect().equals(nuparquet.open(synth_out).scan("scenes").collect())


@pytest.fixture
def http_root(tmp_path):
    """The URL of an empty directory served over HTTP on 127.0.0.1 (no manifest.json behind it)."""
    import functools
    import threading
    from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

    class Quiet(SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    (tmp_path / "served").mkdir()
    server = ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(tmp_path / "served")))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    thread.join()


def test_a_url_without_a_manifest_is_a_format_error_naming_the_url_and_the_manifest(http_root):
    with pytest.raises(FormatError) as error:
        nuparquet.open(f"{http_root}/out/")  # the trailing slash is not part of the root
    message = str(error.value)
    assert message.startswith(f"{http_root}/out: cannot read manifest.json (") and "404" in message
    assert message.endswith("); not a nuparquet output, or the storage_options do not reach it?")


@pytest.mark.parametrize("format_version", ["1", 1.0, None, True, [1]])
def test_open_a_non_integer_format_version_is_a_format_error(tmp_path, synth_out, format_version, capsys):
    out = _with_manifest(tmp_path, synth_out, format_version=format_version)
    with pytest.raises(FormatError, match="no integer format_version"):
        nuparquet.open(out)
    assert main(["info", str(out)]) == 1 and "no integer format_version" in capsys.readouterr().err


@pytest.mark.parametrize("datasets", [{}, [], None, "frames"])
def test_open_a_manifest_without_datasets_is_a_format_error(tmp_path, synth_out, datasets, capsys):
    out = _with_manifest(tmp_path, synth_out, datasets=datasets)
    with pytest.raises(FormatError, match="lists no datasets"):
        nuparquet.open(out)
    assert main(["info", str(out)]) == 1 and "lists no datasets" in capsys.readouterr().err


def test_open_a_manifest_that_is_not_json_is_a_format_error(tmp_path):
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(FormatError, match="not valid JSON"):
        nuparquet.open(tmp_path)


def test_scan_of_a_dataset_whose_directory_is_gone_is_a_format_error(tmp_path, extract_out):
    ds = nuparquet.open(_with_manifest(tmp_path, extract_out))
    with pytest.raises(FormatError, match="frames.*missing"):
        ds.scan("frames")


# --- SQL ----------------------------------------------------------------------------------------------------------

def test_sql_registers_source_tables_under_three_names(extract_out):
    ds = nuparquet.open(extract_out)
    rows = ds.manifest["datasets"]["tables/sample"]["rows"]
    for name in ('"tables/sample"', "sample", "tables_sample"):
        assert ds.sql(f"SELECT COUNT(*) AS n FROM {name}")["n"].item() == rows, name


def test_sql_joins_datasets_and_agrees_with_the_scan(extract_out):
    ds = nuparquet.open(extract_out)
    result = ds.sql("SELECT s.name, COUNT(*) AS n FROM annotations a JOIN scenes s ON a.scene_token = s.token "
                    "GROUP BY s.name ORDER BY s.name")
    expected = ds.scan("annotations").group_by("scene_name").len().sort("scene_name")
    assert result.rows() == expected.collect().rows()
    assert isinstance(ds.sql("SELECT * FROM frames", lazy=True), pl.LazyFrame)


@pytest.mark.parametrize("query, message", [
    ("SELEC * FROM frames", "sql parser error"),
    ("SELECT * FROM no_such_table", r"no_such_table.*datasets: frames, annotations"),
    ("SELECT no_such_column FROM scenes", "no_such_column"),
])
def test_sql_errors_are_query_errors_with_polars_message(extract_out, query, message):
    with pytest.raises(QueryError, match=message):
        nuparquet.open(extract_out).sql(query)


def test_an_unknown_table_in_sql_lists_the_datasets_and_the_source_tables(synth_out):
    """The hint after polars' message: the manifest's datasets but the source tables, then the source tables by
    their SQL names (the manifest read here as JSON)."""
    names = list(json.loads((synth_out / "manifest.json").read_text())["datasets"])
    derived = [n for n in names if not n.startswith("tables/")]
    tables = [n[len("tables/"):] for n in names if n.startswith("tables/")]
    assert derived and tables
    with pytest.raises(QueryError) as error:
        nuparquet.open(synth_out).sql("SELECT * FROM no_such_table")
    message = str(error.value)
    assert message.startswith("SQL failed: ") and "no_such_table" in message
    assert message.endswith(f" (datasets: {', '.join(derived)}; source tables: {', '.join(tables)}; "
                            'a name with a slash is double-quoted: SELECT * FROM "map/lane"; tables also as sample, '
                            "tables_sample)")


def test_an_sql_error_without_a_message_is_named_by_its_type(synth_out, monkeypatch):
    class Failing:  # polars raising an error whose text is empty (nothing to quote)
        def execute(self, query, eager):
            raise pl.exceptions.ComputeError("")

    ds = nuparquet.open(synth_out)
    monkeypatch.setattr(ds, "sql_context", Failing)
    with pytest.raises(QueryError, match=r"^SQL failed: ComputeError$"):
        ds.sql("SELECT * FROM scenes")


# --- reading only what a one-scene query needs ----------------------------------------------------------------------

def _row_groups_that_may_hold(path, column: str, value: str) -> tuple[int, int]:
    """(row groups whose min/max statistics of `column` admit `value`, row groups in the file)."""
    metadata = pq.ParquetFile(path).metadata
    index = metadata.schema.to_arrow_schema().get_field_index(column)
    may = 0
    for g in range(metadata.num_row_groups):
        stats = metadata.row_group(g).column(index).statistics
        may += stats is None or not stats.has_min_max or stats.min <= value <= stats.max
    return may, metadata.num_row_groups


def _row_groups_read(lazy: pl.LazyFrame, capfd) -> list[tuple[int, int]]:
    """(row groups read, row groups in the file) per Parquet file, from polars' verbose scan log."""
    capfd.readouterr()
    with pl.Config(verbose=True):
        lazy.collect()
    log = capfd.readouterr().err
    found = [(int(a), int(b)) for a, b in re.findall(r"reading (\d+) / (\d+) row groups", log)]
    assert found, f"polars' verbose log no longer reports row groups read:\n{log[-2000:]}"
    return found


@pytest.mark.parametrize("dataset", ["annotations", "frames"])
def test_one_scene_query_reads_only_the_row_groups_holding_that_scene(extract_out, dataset, capfd):
    ds = nuparquet.open(extract_out)
    [path] = sorted((extract_out / dataset).rglob("*.parquet"))
    scene = ds.scan("scenes").select("name").sort("name").collect()["name"][-1]
    may_hold, total = _row_groups_that_may_hold(path, "scene_name", scene)
    assert 0 < may_hold < total  # the statistics can prune: the rest of the test is meaningful
    lazy = ds.scan(dataset).filter(pl.col("scene_name") == scene).select("token")
    assert _row_groups_read(lazy, capfd) == [(may_hold, total)]


def test_canned_queries_for_one_scene_push_the_filter_into_the_scan(extract_out, capfd):
    ds = nuparquet.open(extract_out)
    scene = ds.scan("scenes").select("name").sort("name").collect()["name"][0]
    for dataset, query in (("annotations", queries.class_distribution), ("annotations", queries.points_per_box),
                           ("frames", queries.ego_motion), ("frames", queries.channel_rates)):
        [path] = sorted((extract_out / dataset).rglob("*.parquet"))
        may_hold, total = _row_groups_that_may_hold(path, "scene_name", scene)
        assert 0 < may_hold < total
        assert _row_groups_read(query(ds, scene=scene), capfd) == [(may_hold, total)], query.__name__


def test_one_scene_and_one_channel_filter_is_pushed_into_the_scan_with_only_needed_columns(extract_out):
    ds = nuparquet.open(extract_out)
    lazy = (ds.scan("frames").filter((pl.col("scene_name") == "scene-0916") & (pl.col("channel") == "CAM_FRONT"))
            .select("timestamp", "filename"))
    plan = lazy.explain()
    scan = plan[plan.upper().index("PARQUET SCAN"):]
    # The predicate is evaluated by the Parquet reader (row-group statistics, then rows), not by a separate
    # FILTER over a full read, and only the four columns involved are decoded.
    assert "FILTER" not in plan.upper()
    assert re.search(r"SELECTION:.*scene_name", scan) and re.search(r"SELECTION:.*channel", scan)
    projected, total = map(int, re.search(r"PROJECT (\d+)/(\d+) COLUMNS", scan).groups())
    assert projected == 4 and total == len(ds.scan("frames").collect_schema())
