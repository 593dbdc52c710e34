"""`nuparquet info`, `stats` and `sql`: output parsed (csv/json) and compared with the library and with
counts taken from the JSON; user errors are a message and an exit code, never a traceback."""

from __future__ import annotations

import csv
import io
import json
from collections import Counter
from pathlib import Path

import polars as pl
import pytest

import nuparquet
from conftest import EXTRACT_VERSION, SYNTH_VERSION
from nuparquet import queries
from nuparquet.cli import main as cli_main
from nuparquet.cli.output import records

OURS = ["info", "stats", "sql"]


@pytest.fixture
def run(monkeypatch, capsys):
    """Run `nuparquet ARGS...` through the real entry point; returns (exit code, stdout, stderr)."""
    monkeypatch.setattr(cli_main, "COMMANDS", OURS)  # only the subcommands under test

    def invoke(*argv: str) -> tuple[int, str, str]:
        capsys.readouterr()
        try:
            code = cli_main.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse: --help, usage errors
            code = exc.code
        out, err = capsys.readouterr()
        return code, out, err

    return invoke


@pytest.fixture(scope="module", params=["extract", "synth"])
def case(request):
    """(source JSON folder, converted OUT) for the real extract and a synthetic dataset."""
    if request.param == "extract":
        return request.getfixturevalue("extract_root") / EXTRACT_VERSION, request.getfixturevalue("extract_out")
    return request.getfixturevalue("synth_root") / SYNTH_VERSION, request.getfixturevalue("synth_out")


def load(folder: Path, table: str) -> list[dict]:
    return json.loads((folder / f"{table}.json").read_text())


def category_counts(folder: Path) -> Counter:
    category = {c["token"]: c["name"] for c in load(folder, "category")}
    instance = {i["token"]: category[i["category_token"]] for i in load(folder, "instance")}
    return Counter(instance[a["instance_token"]] for a in load(folder, "sample_annotation"))


def parse_sections(text: str) -> dict[str, list[dict]]:
    """`stats --format csv` output: '# name' lines, each followed by one CSV table."""
    sections, name, lines = {}, None, []
    for line in text.splitlines() + ["# end"]:
        if line.startswith("# "):
            if name is not None:
                sections[name] = list(csv.DictReader(io.StringIO("\n".join(l for l in lines if l))))
            name, lines = line[2:], []
        else:
            lines.append(line)
    return sections


# --- info ---------------------------------------------------------------------------------------------------------

def test_info_json_lists_every_dataset_with_rows_files_and_bytes_on_disk(run, case):
    folder, out = case
    code, stdout, _ = run("info", out, "--format", "json")
    assert code == 0
    info = json.loads(stdout)
    manifest = json.loads((out / "manifest.json").read_text())
    assert info["format_version"] == manifest["format_version"] and info["source"]["version"] == folder.name
    assert [d["dataset"] for d in info["datasets"]] == list(manifest["datasets"])
    for entry in info["datasets"]:
        files = sorted((out / manifest["datasets"][entry["dataset"]]["path"]).rglob("*.parquet"))
        assert entry["rows"] == entry["manifest_rows"] == manifest["datasets"][entry["dataset"]]["rows"]
        assert entry["files"] == len(files) and entry["bytes"] == sum(f.stat().st_size for f in files)
    assert info["total_bytes"] == sum(d["bytes"] for d in info["datasets"])
    rows = {d["dataset"]: d["rows"] for d in info["datasets"]}
    assert rows["tables/sample_annotation"] == rows["annotations"] == len(load(folder, "sample_annotation"))
    assert rows["frames"] == len(load(folder, "sample_data")) and rows["scenes"] == len(load(folder, "scene"))


def test_info_table_and_csv_show_every_dataset(run, extract_out):
    code, stdout, _ = run("info", extract_out)
    assert code == 0 and "format:" in stdout and EXTRACT_VERSION in stdout
    for name in nuparquet.open(extract_out).datasets:
        assert f"\n{name} " in stdout
    code, stdout, _ = run("info", extract_out, "--format", "csv")
    table = list(csv.DictReader(io.StringIO(stdout)))
    assert code == 0 and [r["dataset"] for r in table] == nuparquet.open(extract_out).datasets


def test_info_warns_and_fails_when_row_counts_disagree_with_the_manifest(run, extract_out, tmp_path):
    import shutil

    copy = tmp_path / "out"
    shutil.copytree(extract_out, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["datasets"]["scenes"]["rows"] += 1
    (copy / "manifest.json").write_text(json.dumps(manifest))
    code, _, stderr = run("info", copy)
    assert code == 1 and "scenes has" in stderr and "manifest says" in stderr


@pytest.mark.parametrize("command", [["info"], ["stats"], ["sql", "SELECT 1"]])
def test_commands_on_a_directory_that_is_not_a_nuparquet_output_fail_with_a_message(run, tmp_path, command):
    (tmp_path / "scene.json").write_text("[]")
    code, stdout, stderr = run(command[0], tmp_path, *command[1:])
    assert code == 1 and "not a nuparquet output" in stderr and "Traceback" not in stderr + stdout


@pytest.mark.parametrize("command", OURS)
def test_every_subcommand_has_help(run, command):
    code, stdout, _ = run(command, "--help")
    assert code == 0 and "OUT" in stdout and "--format" in stdout


# --- stats --------------------------------------------------------------------------------------------------------

def expected_sections(folder) -> list[str]:
    """The core sections, then the CAN bus ones when the dataroot has the CAN bus expansion, then the map ones when
    it has the map expansion."""
    has_can_bus = any((folder.parent / "can_bus").glob("*_vehicle_monitor.json"))
    has_map = any((folder.parent / "maps" / "expansion").glob("*.json"))
    return (list(queries.SECTIONS) + (["can_speed", "brake_throttle"] if has_can_bus else [])
            + (["map_surfaces", "ego_on_map"] if has_map else []))


def test_stats_json_equals_the_library_queries(run, case):
    folder, out = case
    code, stdout, _ = run("stats", out, "--format", "json")
    assert code == 0
    printed = json.loads(stdout)
    assert list(printed) == expected_sections(folder)
    lazy = queries.summary(nuparquet.open(out))
    for name, frame in zip(lazy, pl.collect_all(list(lazy.values()))):
        assert len(printed[name]) == frame.height, name
        for got, want in zip(printed[name], records(frame)):
            assert got.keys() == want.keys()
            for key, value in want.items():
                assert got[key] == (pytest.approx(value, rel=1e-12) if isinstance(value, float) else value), (name, key)


def test_stats_csv_class_distribution_counts_equal_the_json(run, case):
    folder, out = case
    code, stdout, _ = run("stats", out, "--format", "csv", "--only", "class_distribution")
    assert code == 0 and not stdout.startswith("#")  # one section: plain CSV
    table = list(csv.DictReader(io.StringIO(stdout)))
    assert {r["category_name"]: int(r["num_annotations"]) for r in table} == category_counts(folder)


def test_stats_csv_prints_every_section_and_per_scene_annotation_counts(run, case):
    folder, out = case
    code, stdout, _ = run("stats", out, "--format", "csv")
    assert code == 0
    sections = parse_sections(stdout)
    assert list(sections) == expected_sections(folder)
    sample_scene = {s["token"]: s["scene_token"] for s in load(folder, "sample")}
    per_scene = Counter(sample_scene[a["sample_token"]] for a in load(folder, "sample_annotation"))
    name = {s["token"]: s["name"] for s in load(folder, "scene")}
    assert {r["name"]: int(r["num_annotations"]) for r in sections["scenes"]} == {
        name[token]: per_scene[token] for token in name}
    attributes = Counter(t for a in load(folder, "sample_annotation") for t in a["attribute_tokens"])
    attribute_name = {a["token"]: a["name"] for a in load(folder, "attribute")}
    assert {r["attribute_name"]: int(r["count"]) for r in sections["attributes"]} == {
        attribute_name[t]: n for t, n in attributes.items()}


def test_stats_for_one_scene_counts_only_that_scene(run, case):
    folder, out = case
    scene = load(folder, "scene")[0]
    code, stdout, _ = run("stats", out, "--scene", scene["name"], "--format", "json", "--only", "scenes",
                          "--only", "class_distribution")
    assert code == 0
    printed = json.loads(stdout)
    samples = {s["token"] for s in load(folder, "sample") if s["scene_token"] == scene["token"]}
    expected = sum(a["sample_token"] in samples for a in load(folder, "sample_annotation"))
    assert [r["name"] for r in printed["scenes"]] == [scene["name"]]
    assert sum(r["num_annotations"] for r in printed["class_distribution"]) == expected


def test_stats_table_is_readable_and_matches_list_categories_numbers(run, extract_out):
    code, stdout, _ = run("stats", extract_out)
    assert code == 0
    cd = queries.class_distribution(nuparquet.open(extract_out)).collect()
    row = cd.row(0, named=True)
    assert f"{row['width_mean']:.2f}\u00b1{row['width_std']:.2f}" in stdout
    for title in ("Categories", "Attributes", "Visibility", "Points per box", "Distance", "Tracks", "Ego motion",
                  "Frames per channel", "Scenes"):
        assert f"== {title}" in stdout, title
    assert "Traceback" not in stdout


def test_stats_unknown_scene_is_a_usage_error_with_suggestions(run, extract_out):
    code, _, stderr = run("stats", extract_out, "--scene", "scene-091")
    assert code == 2 and "unknown scene 'scene-091' (did you mean scene-0916" in stderr


def test_stats_plots_writes_four_png_charts_and_two_from_the_can_bus(run, synth_out, tmp_path):
    import matplotlib.image

    code, stdout, _ = run("stats", synth_out, "--plots", tmp_path / "plots", "--only", "attributes")
    assert code == 0 and "wrote 6 charts" in stdout
    names = sorted(p.name for p in (tmp_path / "plots").iterdir())
    assert names == ["can_speed.png", "class_distribution.png", "distance_histogram.png", "ego_speed.png",
                     "lidar_points_per_box.png", "steering.png"]
    for name in names:
        path = tmp_path / "plots" / name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 300 and image.shape[1] > 500 and image[..., :3].std() > 0.01  # not blank


def test_can_speed_chart_names_vehicle_monitor_speed_as_the_vehicle_speed(synth_out, tmp_path, monkeypatch):
    """vehicle_monitor.vehicle_speed is the vehicle's speed (the devkit tutorial's "Vehicle speed"); the wheel
    speeds are zoe_veh_info's FL_wheel_speed, ... (issue 24: the chart called it "CAN wheel speed")."""
    from nuparquet.queries.can_bus import speed_over_time
    from nuparquet.rendering.pictures import charts

    figures = []
    saved = charts._save
    monkeypatch.setattr(charts, "_save", lambda fig, path: (figures.append(fig), saved(fig, path))[1])
    speeds = speed_over_time(nuparquet.open(synth_out)).collect()
    charts.plot_can_speed(speeds, tmp_path / "can_speed.png", scene=speeds["scene_name"][0])
    labels = [t.get_text() for t in figures[0].axes[0].get_legend().get_texts()]
    assert any("vehicle_monitor vehicle_speed" in label for label in labels)
    assert not any("wheel" in label for label in labels)


# --- sql ----------------------------------------------------------------------------------------------------------

def test_sql_csv_result_equals_counts_from_the_json(run, case):
    folder, out = case
    code, stdout, _ = run("sql", out, "SELECT category_name, COUNT(*) AS n FROM annotations GROUP BY category_name "
                          "ORDER BY category_name", "--format", "csv")
    assert code == 0
    table = list(csv.DictReader(io.StringIO(stdout)))
    assert {r["category_name"]: int(r["n"]) for r in table} == category_counts(folder)


def test_sql_json_over_a_source_table_equals_the_json_records(run, case):
    folder, out = case
    code, stdout, _ = run("sql", out, 'SELECT token, timestamp, scene_token FROM "tables/sample" ORDER BY token',
                          "--format", "json")
    assert code == 0
    expected = sorted(({k: s[k] for k in ("token", "timestamp", "scene_token")} for s in load(folder, "sample")),
                      key=lambda r: r["token"])
    assert json.loads(stdout) == expected


def test_sql_csv_keeps_nested_columns_as_json_text(run, extract_out):
    code, stdout, _ = run("sql", extract_out, "SELECT token, size, attribute_names FROM annotations LIMIT 5",
                          "--format", "csv")
    assert code == 0
    for row in csv.DictReader(io.StringIO(stdout)):
        assert len(json.loads(row["size"])) == 3 and isinstance(json.loads(row["attribute_names"]), list)


def test_sql_table_output_prints_the_rows_and_their_count(run, extract_out):
    code, stdout, _ = run("sql", extract_out, "SELECT name, nbr_samples FROM scenes ORDER BY name")
    assert code == 0 and "scene-0523" in stdout and "scene-0916" in stdout and "(2 rows)" in stdout


@pytest.mark.parametrize("query, message", [
    ("SELEC name FROM scenes", "sql parser error"),
    ("SELECT * FROM no_such_table", "no_such_table"),
    ("SELECT no_such_column FROM scenes", "no_such_column"),
])
def test_sql_errors_exit_1_with_a_message_and_no_traceback(run, extract_out, query, message):
    code, stdout, stderr = run("sql", extract_out, query)
    assert code == 1 and stderr.startswith("error: SQL failed") and message in stderr
    assert "Traceback" not in stderr + stdout and stdout == ""


def test_stats_on_a_dataset_without_annotations_prints_empty_sections(run, extract_out, tmp_path):
    """A v1.0-test style conversion: annotations and instances hold no rows."""
    import shutil

    import pyarrow.parquet as pq

    copy = tmp_path / "out"
    shutil.copytree(extract_out, copy)
    for dataset in ("annotations", "instances"):
        for path in (copy / dataset).rglob("*.parquet"):
            pq.write_table(pq.read_table(path).slice(0, 0), path)
    code, stdout, _ = run("stats", copy, "--format", "json", "--plots", tmp_path / "plots")
    assert code == 0
    printed = json.loads(stdout)
    for section in ("class_distribution", "attributes", "visibility", "points_per_box", "distance_histogram",
                    "tracks"):
        assert printed[section] == [], section
    assert all(r["num_annotations_list_scenes"] == 0 for r in printed["scenes"])
    assert printed["channel_rates"] and len(list((tmp_path / "plots").glob("*.png"))) == 6  # 2 from the CAN bus


def table_sections(text: str) -> dict[str, list[dict[str, str]]]:
    """`stats` table output: each '== Title' line, then a header, a dashes line and the rows; the columns' spans
    are read from the dashes line (headers such as 'lidar mean' hold a space)."""
    sections, lines = {}, text.splitlines()
    for i, line in enumerate(lines):
        if not line.startswith("== "):
            continue
        header, dashes = lines[i + 1], lines[i + 2]
        spans, start = [], 0
        for width in (len(d) for d in dashes.split("  ")):
            spans.append((start, start + width))
            start += width + 2
        names = [header[a:b].strip() for a, b in spans]
        rows = []
        for row in lines[i + 3:]:
            if not row or row.startswith(("== ", "…")):
                break
            rows.append({name: row[a:b].strip() for name, (a, b) in zip(names, spans)})
        sections[line[3:]] = rows
    return sections


def section(sections: dict, title: str) -> list[dict[str, str]]:
    return next(rows for name, rows in sections.items() if name.startswith(title))


def close_to_printed(cell: str, expected: float) -> bool:
    """A table cell (rounded to the decimals it shows) equals `expected`."""
    decimals = len(cell.split(".")[1]) if "." in cell else 0
    return abs(float(cell) - expected) <= 0.5 * 10 ** -decimals + 1e-9


def test_stats_table_shows_scenes_visibility_and_lidar_points_per_box_as_counted_from_the_json(run, synth_root,
                                                                                                synth_out):
    """The terminal tables (`display`): the scenes' sample and annotation counts, visibility as one column per
    level, and the points-per-box statistics (numpy.percentile's linear rule), against the JSON."""
    import numpy as np

    folder = synth_root / SYNTH_VERSION
    code, stdout, _ = run("stats", synth_out)
    assert code == 0
    sections = table_sections(stdout)

    scene_name = {s["token"]: s["name"] for s in load(folder, "scene")}
    sample_scene = {s["token"]: scene_name[s["scene_token"]] for s in load(folder, "sample")}
    annotations = load(folder, "sample_annotation")
    scenes = section(sections, "Scenes")
    assert {r["name"]: int(r["nbr_samples"]) for r in scenes} == Counter(sample_scene.values())
    assert {r["name"]: int(r["annotations"]) for r in scenes} == Counter(sample_scene[a["sample_token"]]
                                                                         for a in annotations)

    category = {c["token"]: c["name"] for c in load(folder, "category")}
    category_of = {i["token"]: category[i["category_token"]] for i in load(folder, "instance")}
    by_category: dict[str, list[dict]] = {}
    for a in annotations:
        by_category.setdefault(category_of[a["instance_token"]], []).append(a)
    levels = sorted({f"v{int(a['visibility_token'])}" for a in annotations})
    visibility = section(sections, "Visibility")
    assert list(visibility[0]) == ["category_name", *levels]
    assert {r["category_name"]: {v: int(r[v]) for v in levels} for r in visibility} == {
        name: {v: sum(f"v{int(a['visibility_token'])}" == v for a in anns) for v in levels}
        for name, anns in by_category.items()}

    points = section(sections, "Points per box")
    assert list(points[0])[:8] == ["category_name", "boxes", "lidar mean", "lidar p05", "lidar p50", "lidar p95",
                                   "lidar max", "lidar zero"]
    assert [r["category_name"] for r in points] == sorted(by_category)
    for row in points:
        anns = by_category[row["category_name"]]
        assert int(row["boxes"]) == len(anns)
        for sensor in ("lidar", "radar"):
            counts = np.array([a[f"num_{sensor}_pts"] for a in anns if a[f"num_{sensor}_pts"] >= 0])
            assert close_to_printed(row[f"{sensor} mean"], counts.mean()), row
            for q in (5, 50, 95):
                assert close_to_printed(row[f"{sensor} p{q:02d}"], np.percentile(counts, q)), (row, q)
            assert int(row[f"{sensor} max"]) == counts.max()
            assert row[f"{sensor} zero"] == f"{(counts == 0).mean():.1%}"


def test_stats_only_a_section_outside_the_default_prints_its_table_of_annotations_and_instances(run, synth_root,
                                                                                              synth_out):
    """--only class_distribution_by_scene (a section a plain `stats` does not compute) prints the categories of
    each scene: annotations, and instances (distinct instance tokens), counted from the JSON, under the headers
    'annotations' and 'instances'."""
    folder = synth_root / SYNTH_VERSION
    code, stdout, _ = run("stats", synth_out, "--only", "class_distribution_by_scene")
    assert code == 0
    scene_name = {s["token"]: s["name"] for s in load(folder, "scene")}
    sample_scene = {s["token"]: scene_name[s["scene_token"]] for s in load(folder, "sample")}
    category = {c["token"]: c["name"] for c in load(folder, "category")}
    category_of = {i["token"]: category[i["category_token"]] for i in load(folder, "instance")}
    annotations, instances = Counter(), {}
    for a in load(folder, "sample_annotation"):
        key = (sample_scene[a["sample_token"]], category_of[a["instance_token"]])
        annotations[key] += 1
        instances.setdefault(key, set()).add(a["instance_token"])
    rows = section(table_sections(stdout), "Categories per scene")
    assert list(rows[0])[:4] == ["scene_name", "category_name", "annotations", "instances"]
    assert {(r["scene_name"], r["category_name"]): (int(r["annotations"]), int(r["instances"])) for r in rows} == {
        key: (n, len(instances[key])) for key, n in annotations.items()}
    assert len(scene_name) > 1 and any(len(tokens) > 1 for tokens in instances.values())


def test_stats_table_counts_annotations_of_unknown_visibility_in_a_v_question_mark_column(run, layouts_root,
                                                                                            layouts_out):
    """An empty visibility token (derived datasets write them) has no level: the terminal table counts such boxes in
    a column of their own, 'v?', after v1..v4, per category, as counted from the JSON."""
    folder = layouts_root / SYNTH_VERSION
    code, stdout, _ = run("stats", layouts_out, "--only", "visibility")
    assert code == 0
    category = {c["token"]: c["name"] for c in load(folder, "category")}
    category_of = {i["token"]: category[i["category_token"]] for i in load(folder, "instance")}
    expected: dict[str, Counter] = {}
    for a in load(folder, "sample_annotation"):
        level = f"v{int(a['visibility_token'])}" if a["visibility_token"] else "v?"
        expected.setdefault(category_of[a["instance_token"]], Counter())[level] += 1
    levels = sorted({level for counts in expected.values() for level in counts} - {"v?"}) + ["v?"]
    assert sum(counts["v?"] for counts in expected.values()) > 0
    rows = section(table_sections(stdout), "Visibility")
    assert list(rows[0]) == ["category_name", *levels]
    assert {r["category_name"]: {v: int(r[v]) for v in levels} for r in rows} == {
        name: {v: counts[v] for v in levels} for name, counts in expected.items()}


def test_json_outputs_are_laid_out_alike_one_space_indent_keys_in_order(run, synth_out):
    """`info`, `stats` and `sql` with --format json print the same layout: the document indented by one space per
    level, keys in the order written, then a newline (output one can diff across commands and runs)."""
    outputs = [run("info", synth_out, "--format", "json"),
               run("stats", synth_out, "--only", "scenes", "--format", "json"),
               run("sql", synth_out, "SELECT name FROM scenes ORDER BY name", "--format", "json")]
    for code, stdout, _ in outputs:
        assert code == 0
        assert stdout == json.dumps(json.loads(stdout), indent=1) + "\n"
        assert stdout.startswith(("{\n \"", "[\n {\n  \""))
