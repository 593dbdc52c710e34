"""`nuparquet report`: the site's files, every link inside it, the scene table and statistics against the JSON
tables, the videos and keyframe renderings decoded, the options and the failures (the pages in a real browser are
tested in test_report_browser.py)."""

from __future__ import annotations

import copy
import json
import re
import shutil
from datetime import datetime, timedelta, timezone
from html.parser import HTMLParser
from pathlib import Path

import av
import cv2
import polars as pl
import pytest

import nuparquet
from nuparquet.cli.main import main
from nuparquet.dataset.selection import SceneSelection
from nuparquet.errors import UsageError
from nuparquet.site import ReportOptions, build_report
from nuparquet.site.facts import dataset_facts, local_start, log_utc_offset_min, time_of_day, weather_words
from nuparquet.site.html import cell_text

VERSION = "v1.0-synth"
SCENES = ["scene-0001", "scene-0002"]


# Elements that hold other elements, never text of their own: text in them is stray (a fragment of markup written
# outside its element); the void elements have no end tag.
CONTAINERS = {"html", "head", "body", "header", "main", "div", "table", "thead", "tbody", "tr", "figure", "details",
              "select", "video"}
VOID = {"meta", "link", "img", "input", "br", "hr", "source"}


class Page(HTMLParser):
    """Every URL a page refers to (href, src), its tables as lists of rows of cell texts (by table id or the id of
    the <details> around it) and their class attributes (`table_classes`, by the same keys), the texts of its headings and paragraphs (`texts["h2"]`, `texts["p"]`), and
    `problems`: what makes it malformed (an end tag that closes no open element, an element left open, text
    outside any element or directly inside a container)."""

    def __init__(self, text: str):
        super().__init__()
        self.urls: list[str] = []
        self.tables: dict[str, list[list[str]]] = {}
        self.table_classes: dict[str, str] = {}
        self.texts: dict[str, list[str]] = {"h1": [], "h2": [], "p": []}
        self.problems: list[str] = []
        self._open: list[str] = []
        self._texts: list[tuple[str, list[str]]] = []
        self._context: list[str] = []
        self._table: list[list[str]] | None = None
        self._cell: list[str] | None = None
        self.feed(text)
        self.close()
        if self._open:
            self.problems.append(f"left open: {self._open}")

    def handle_starttag(self, tag, attrs):
        if tag not in VOID:
            self._open.append(tag)
        if tag in self.texts:
            self._texts.append((tag, []))
        attrs = dict(attrs)
        for name in ("href", "src"):
            if name in attrs:
                self.urls.append(attrs[name])
        if tag == "details" and "id" in attrs:
            self._context.append(attrs["id"])
        if tag == "table":
            self._table = []
            key = attrs.get("id") or (self._context[-1] if self._context else f"table{len(self.tables)}")
            self.tables[key] = self._table
            self.table_classes[key] = attrs.get("class") or ""
        if tag == "tr" and self._table is not None:
            self._table.append([])
        if tag in ("td", "th") and self._table is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if not self._open or self._open[-1] != tag:
            self.problems.append(f"</{tag}> closes no open element (open: {self._open})")
        else:
            self._open.pop()
        if tag in self.texts and self._texts and self._texts[-1][0] == tag:
            self.texts[tag].append("".join(self._texts.pop()[1]).strip())
        if tag in ("td", "th") and self._cell is not None:
            self._table[-1].append("".join(self._cell).strip())
            self._cell = None
        if tag == "table":
            self._table = None
        if tag == "details" and self._context:
            self._context.pop()

    def handle_data(self, data):
        if data.strip() and (not self._open or self._open[-1] in CONTAINERS):
            self.problems.append(f"text {data.strip()!r} in <{self._open[-1] if self._open else 'nothing'}>")
        for _, parts in self._texts:
            parts.append(data)
        if self._cell is not None:
            self._cell.append(data)


def rows_of(table: list[list[str]]) -> list[dict[str, str]]:
    header, *rows = table
    return [dict(zip(header, row)) for row in rows]


class Tables:
    def __init__(self, root: Path):
        def table(name):
            return json.loads((root / VERSION / f"{name}.json").read_text())

        self.root = root
        self.scene = {s["name"]: s for s in table("scene")}
        self.log = {lg["token"]: lg for lg in table("log")}
        self.samples = table("sample")
        self.annotations = table("sample_annotation")
        self.instances = table("instance")
        self.sample_data = table("sample_data")
        # the scenes with CAN bus data: those the generator wrote a pose file for (can_bus/<scene>_pose.json)
        self.can_bus = {p.name.removesuffix("_pose.json") for p in (root / "can_bus").glob("*_pose.json")}

    def samples_of(self, scene: str) -> list[dict]:
        token = self.scene[scene]["token"]
        return sorted((s for s in self.samples if s["scene_token"] == token), key=lambda s: s["timestamp"])

    def annotations_of(self, scene: str) -> list[dict]:
        samples = {s["token"] for s in self.samples_of(scene)}
        return [a for a in self.annotations if a["sample_token"] in samples]

    def local_start(self, scene: str) -> tuple[datetime, str]:
        """The first sample's time in the UTC offset its log's name ends with (n008-2018-10-12-08-10-14-0400), and
        that offset as the report names it ("UTC-04:00")."""
        logfile = self.log[self.scene[scene]["log_token"]]["logfile"]
        sign, hours, minutes = re.search(r"([+-])(\d\d)(\d\d)$", logfile).groups()
        offset = timedelta(hours=int(hours), minutes=int(minutes)) * (1 if sign == "+" else -1)
        utc = datetime(1970, 1, 1, tzinfo=timezone.utc) + timedelta(microseconds=self.samples_of(scene)[0]["timestamp"])
        return utc + offset, f"UTC{sign}{hours}:{minutes}"


@pytest.fixture(scope="module")
def tables(synth_root) -> Tables:
    return Tables(synth_root)


def test_the_site_has_an_index_a_page_per_scene_videos_well_formed_pages_and_only_local_links(synth_report):
    result, events = synth_report
    out = result.out
    assert result.scenes == SCENES and result.problems == {}
    assert (out / "index.html").is_file() and (out / "assets" / "report.css").is_file()
    pages = [out / "index.html", *(out / "scenes" / f"{s}.html" for s in SCENES)]
    assert sorted((out / "scenes").glob("*.html")) == sorted(pages[1:])
    checked = 0
    for page in pages:
        text = page.read_text()
        assert "http://" not in text and "https://" not in text and "//cdn" not in text
        assert Page(text).problems == [], page.name
        for url in Page(text).urls:
            if url.startswith(("#", "data:")):
                continue
            assert not url.startswith("/") and "://" not in url, url
            target = (page.parent / url.split("#")[0]).resolve()
            assert target.is_file() and out.resolve() in target.parents, f"{page.name}: {url}"
            checked += 1
    assert checked > 20
    assert events[-1].finished and events[-1].done == events[-1].total
    assert not list(out.parent.glob(".*partial*"))


def test_scene_table_rows_are_the_scenes_of_the_json_tables(synth_report, tables):
    result, _ = synth_report
    rows = rows_of(Page((result.out / "index.html").read_text()).tables["scene-table"])
    assert [r["scene"] for r in rows] == SCENES
    for row in rows:
        scene = tables.scene[row["scene"]]
        log = tables.log[scene["log_token"]]
        samples = tables.samples_of(row["scene"])
        assert row["location"] == log["location"] and row["date"] == log["date_captured"]
        assert row["samples"] == str(len(samples)) == str(scene["nbr_samples"])
        assert row["annotations"] == str(len(tables.annotations_of(row["scene"])))
        duration = (samples[-1]["timestamp"] - samples[0]["timestamp"]) / 1e6
        assert row["duration s"] == f"{duration:.2f}"
        # the local time: the log name's offset (n008-2018-10-12-08-10-14-0400) applied to the first sample
        local, _ = tables.local_start(row["scene"])
        assert row["local start"] == local.strftime("%H:%M")
        assert row["time of day"] == ("morning" if 6 <= local.hour < 12 else "afternoon" if local.hour < 17
                                      else "evening" if local.hour < 20 else "night") if local.hour >= 6 else "night"
        assert row["description"] == scene["description"]
    assert [r["CAN bus"] for r in rows] == ["yes", "no"]  # the generator leaves the last scene without CAN bus
    assert tables.can_bus == {"scene-0001"}


def test_index_outline_dataset_facts_and_no_subset_note(synth_report, tables):
    """The index's sections in order, its dataset facts counted from the JSON tables, and no note of a subset: the
    report covers every scene."""
    result, _ = synth_report
    page = Page(result.index.read_text())
    assert page.texts["h2"] == ["Dataset", f"Scenes ({len(SCENES)} of {len(SCENES)} shown)", "Charts", "Statistics"]
    facts = dict(page.tables["table0"])  # the first table: (label, value) rows
    assert (facts["scenes"], facts["samples (keyframes)"], facts["sensor frames"], facts["annotations"],
            facts["instances (tracks)"]) == (f"{len(tables.scene):,}", f"{len(tables.samples):,}",
                                             f"{len(tables.sample_data):,}", f"{len(tables.annotations):,}",
                                             f"{len(tables.instances):,}")
    assert facts["CAN bus"] == "converted" and facts["sensor points"] == "lidar_points, radar_points"
    # the header's subtitle and the statistics tables' "N more rows not shown", nothing else
    assert [p for p in page.texts["p"] if not p.endswith("more rows not shown")] == ["nuparquet dataset report"]


def test_dataset_facts_count_the_json_tables_and_leave_samples_blank_without_the_sample_table(synth_points_out,
                                                                                              tables):
    from nuparquet.dataset import Dataset, as_dataset

    dataset = as_dataset(synth_points_out)
    facts = dict(dataset_facts(dataset))
    assert (facts["scenes"], facts["samples (keyframes)"], facts["sensor frames"], facts["annotations"],
            facts["instances (tracks)"]) == (str(len(tables.scene)), str(len(tables.samples)),
                                             str(len(tables.sample_data)), str(len(tables.annotations)),
                                             str(len(tables.instances)))
    # a dataset whose manifest lists no tables/sample (the constructor takes any manifest): the samples line is
    # blank, every other count the same
    manifest = copy.deepcopy(dataset.manifest)
    del manifest["datasets"]["tables/sample"]
    without = dict(dataset_facts(Dataset(dataset.root, manifest)))
    assert without["samples (keyframes)"] == ""
    assert {k: v for k, v in without.items() if k not in ("samples (keyframes)", "datasets")} == \
        {k: v for k, v in facts.items() if k not in ("samples (keyframes)", "datasets")}
    # the sensors by modality, from sensor.json; "none" for a modality the dataset lacks
    sensors = json.loads((tables.root / VERSION / "sensor.json").read_text())
    for modality in ("camera", "lidar", "radar"):
        expected = {s["channel"] for s in sensors if s["modality"] == modality}
        assert expected and set(facts[f"{modality}s"].split(", ")) == expected, modality
    manifest = copy.deepcopy(dataset.manifest)
    manifest["channels"]["radars"] = []
    assert dict(dataset_facts(Dataset(dataset.root, manifest)))["radars"] == "none"
    # the datasets' count and the size of their Parquet files, summed from the folder itself
    parquet_bytes = sum(p.stat().st_size for p in Path(synth_points_out).rglob("*.parquet"))
    assert parquet_bytes > 1e5
    assert facts["datasets"] == f"{len(dataset.manifest['datasets'])} ({parquet_bytes / 1e6:,.1f} MB of Parquet)"


def test_statistics_tables_are_the_canned_queries(synth_report, tables):
    result, _ = synth_report
    page = Page((result.out / "index.html").read_text())
    rows = rows_of(page.tables["class_distribution"])
    assert sum(int(r["num_annotations"].replace(",", "")) for r in rows) == len(tables.annotations)
    for section in ("attributes", "visibility", "tracks", "channel_rates", "can_speed", "lidarseg"):
        assert section in page.tables and len(page.tables[section]) > 1, section
    charts = [u for u in page.urls if u.startswith("assets/plots/")]
    assert {Path(c).name for c in charts} >= {"class_distribution.png", "distance_histogram.png", "ego_speed.png",
                                               "can_speed.png", "steering.png"}
    assert all((result.out / c).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for c in charts)


def test_videos_hold_one_frame_per_keyframe_and_pages_say_their_duration(synth_report, tables):
    result, _ = synth_report
    for scene in SCENES:
        keyframes = len(tables.samples_of(scene))
        with av.open(str(result.out / "videos" / f"{scene}.mp4")) as video:
            stream = video.streams.video[0]
            assert stream.codec_context.name == "h264"
            frames = sum(1 for _ in video.decode(video=0))
        assert frames == keyframes == result.videos[scene]["frames_written"]
        text = (result.out / "scenes" / f"{scene}.html").read_text()
        assert f'src="../videos/{scene}.mp4"' in text
        assert f"{keyframes} keyframes at 2 fps ({keyframes / 2:.1f} s)" in text


def test_keyframe_renderings_and_can_bus_plots(synth_report, synth_root, tables):
    result, _ = synth_report
    for scene in SCENES:
        folder = result.out / "scenes" / scene
        stills = sorted(folder.glob("still-*.jpg"))
        assert len(stills) == min(4, len(tables.samples_of(scene)))
        image = cv2.imread(str(stills[0]))
        sample_image = cv2.imread(str(next((synth_root / "samples" / "CAM_FRONT").glob("*.jpg"))))
        assert image.shape[:2] == (sample_image.shape[0] // 2, sample_image.shape[1] // 2)
        n = len(tables.samples_of(scene))
        assert [s[1:] for s in result.assets[scene]["stills"]] == [[round(k * (n - 1) / 3), n] for k in range(4)]
        page = (result.out / "scenes" / f"{scene}.html").read_text()
        assert all(f"keyframe {round(k * (n - 1) / 3) + 1} of {n}" in page for k in range(4))
    assert sorted(p.name for p in (result.out / "scenes" / "scene-0001").glob("*.png")) == ["can_speed.png",
                                                                                         "steering.png"]
    assert not list((result.out / "scenes" / "scene-0002").glob("*.png"))
    assert "no CAN bus messages for this scene" in (result.out / "scenes" / "scene-0002.html").read_text()


def test_scene_page_lists_its_categories(synth_report, tables, synth_root):
    result, _ = synth_report
    categories = {c["token"]: c["name"] for c in json.loads((synth_root / VERSION / "category.json").read_text())}
    instances = {i["token"]: categories[i["category_token"]]
                 for i in json.loads((synth_root / VERSION / "instance.json").read_text())}
    for scene in SCENES:
        page = Page((result.out / "scenes" / f"{scene}.html").read_text())
        rows = rows_of(page.tables["table1"])
        expected: dict[str, int] = {}
        for annotation in tables.annotations_of(scene):
            name = instances[annotation["instance_token"]]
            expected[name] = expected.get(name, 0) + 1
        assert {r["category_name"]: int(r["num_annotations"].replace(",", "")) for r in rows} == expected


@pytest.mark.parametrize(("description", "hour", "expected"), [
    ("Night, rain, parked cars", 14, "night"), ("Cruising", 5, "night"), ("Cruising", 6, "morning"),
    ("Cruising", 11, "morning"), ("Cruising", 12, "afternoon"), ("Cruising", 16, "afternoon"),
    ("Cruising", 17, "evening"), ("Cruising", 19, "evening"), ("Cruising", 20, "night"), ("Cruising", None, ""),
])
def test_time_of_day(description, hour, expected):
    assert time_of_day(hour, description) == expected


def test_weather_words_and_log_offsets():
    assert weather_words("Rainy night, wet road, overtaking, sunlight glare") == ["rain", "wet", "sun", "night",
                                                                                 "glare"]
    assert weather_words("Parking lot, bicycle rack, peds") == []
    assert weather_words("Nightclub") == ["night"]  # word prefixes, as descriptions spell "Night," / "nighttime"
    assert log_utc_offset_min("n008-2018-08-30-10-33-52-0400") == -240
    assert log_utc_offset_min("n015-2018-10-08-15-36-50+0800") == 480
    assert log_utc_offset_min("n015-2018-10-08-15-36-50+0530") == 330
    assert log_utc_offset_min("host-a004-lidar0-1232815252301696606") is None


def test_local_start_from_the_log_offset_else_the_locations_zone():
    # 2018-08-30 14:35:16 UTC: 10:35 in Boston (EDT, UTC-4); 2018-12-30 14:35:16 UTC: 09:35 (EST, UTC-5)
    summer, winter = 1535639716699138, 1535639716699138 + 122 * 86_400_000_000
    assert local_start(summer, "n008-2018-08-30-10-33-52-0400", None)[0].strftime("%H:%M") == "10:35"
    assert local_start(summer, "n008-2018-08-30-10-33-52-0400", None)[1] == "UTC-04:00"
    assert local_start(summer, None, "boston-seaport")[0].strftime("%H:%M") == "10:35"
    assert local_start(winter, None, "boston-seaport")[0].strftime("%H:%M") == "09:35"
    assert local_start(summer, None, "singapore-onenorth")[0].strftime("%H:%M") == "22:35"
    assert local_start(summer, "host-a004", "palo alto") == (None, "")


def test_scenes_subset_and_no_videos(synth_points_out, tables, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", str(synth_points_out), "--out", str(out), "--scenes", "scene-0002", "--no-videos",
                 "--quiet"]) == 0
    assert "wrote the report of 1 scene(s)" in capsys.readouterr().out
    index = Page((out / "index.html").read_text())
    assert [r["scene"] for r in rows_of(index.tables["scene-table"])] == ["scene-0002"]
    rows = rows_of(index.tables["class_distribution"])
    assert sum(int(r["num_annotations"].replace(",", "")) for r in rows) == len(tables.annotations_of("scene-0002"))
    assert "1 selected scene(s)" in (out / "index.html").read_text()
    # the scene's local start (its log name's offset) and CAN bus (none: the generator writes none for the last scene)
    (row,) = rows_of(index.tables["scene-table"])
    local, zone = tables.local_start("scene-0002")
    assert (row["local start"], row["CAN bus"]) == (local.strftime("%H:%M"), "no") and "scene-0002" not in tables.can_bus
    page = Page((out / "scenes" / "scene-0002.html").read_text())
    facts = dict(page.tables["table0"])
    assert facts["local start"] == f"{local.strftime('%H:%M')} ({zone})"
    scene, log = tables.scene["scene-0002"], tables.log[tables.scene["scene-0002"]["log_token"]]
    assert (facts["description"], facts["location"], facts["date"]) == (scene["description"], log["location"],
                                                                        log["date_captured"])
    assert not (out / "videos").exists() and not list((out / "scenes").rglob("*.jpg"))
    assert "no video" in (out / "scenes" / "scene-0002.html").read_text()
    # report.js sorts the tables of class "sortable": every table of rows (the scene table, each statistics table,
    # the scene's categories) is one; the facts tables (label, value) are not
    assert page.table_classes == {"table0": "facts", "table1": "sortable"} and len(page.tables["table1"]) > 1
    assert index.table_classes["table0"] == "facts" and len(index.table_classes) > 3
    assert {k: c for k, c in index.table_classes.items() if k != "table0"} == \
        {k: "sortable" for k in index.table_classes if k != "table0"}
    # no CAN bus: no speed or steering chart (its ego-pose speeds alone are not charted)
    assert not list((out / "scenes" / "scene-0002").glob("*.png"))
    assert "no CAN bus messages for this scene" in (out / "scenes" / "scene-0002.html").read_text()


def test_a_report_without_videos_still_charts_the_can_bus(synth_points_out, tables, tmp_path):
    """--no-videos leaves out the videos and the keyframe renderings, not the CAN bus: scene-0001 (the generator
    wrote its CAN bus files) gets its speed and steering charts, shown on its page. Built in this test's process."""
    scene = "scene-0001"
    assert scene in tables.can_bus
    result = build_report(synth_points_out, SceneSelection(scenes=(scene,)), tmp_path / "report",
                          ReportOptions(videos=False))
    charts = sorted((result.out / "scenes" / scene).iterdir())
    assert [p.name for p in charts] == ["can_speed.png", "steering.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in charts)
    page = Page((result.out / "scenes" / f"{scene}.html").read_text())
    assert sorted(u for u in page.urls if u.endswith(".png")) == [f"{scene}/can_speed.png", f"{scene}/steering.png"]
    assert "no CAN bus messages" not in (result.out / "scenes" / f"{scene}.html").read_text()


def test_existing_output_unknown_scene_and_missing_dataroot_are_refused(synth_points_out, tmp_path, capsys):
    out = tmp_path / "report"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["report", str(synth_points_out), "--out", str(out), "--no-videos", "--quiet"]) == 2
    assert "already exists; pass --overwrite" in capsys.readouterr().err
    assert (out / "keep.txt").read_text() == "mine"
    assert main(["report", str(synth_points_out), "--out", str(tmp_path / "r"), "--scenes", "scene-9999"]) == 2
    assert "unknown scene 'scene-9999'; valid scenes: scene-0001, scene-0002" in capsys.readouterr().err
    assert main(["report", str(synth_points_out), "--out", str(synth_points_out / "r")]) == 2
    assert "/r is inside the converted dataset " in capsys.readouterr().err  # not written into the Parquet's folder
    with pytest.raises(UsageError, match="--no-videos"):
        build_report(nuparquet.open(synth_points_out, dataroot=tmp_path / "nowhere"), None, tmp_path / "r")
    assert main(["report", str(synth_points_out), "--out", str(out), "--no-videos", "--quiet", "--overwrite"]) == 0
    assert not (out / "keep.txt").exists() and (out / "index.html").is_file()


def test_a_scene_without_images_gets_a_page_that_says_so(synth_root, synth_points_out, tmp_path, capsys):
    """The process pool renders the videos and stills; scene-0002's images are gone: its page explains, the rest
    of the report is whole."""
    dataroot = tmp_path / "data"
    shutil.copytree(synth_root, dataroot)
    frames = (pl.scan_parquet(f"{synth_points_out}/frames/**/*.parquet")
              .filter((pl.col("scene_name") == "scene-0002") & (pl.col("modality").cast(pl.String) == "camera"))
              .select("filename").collect()["filename"].to_list())
    for name in frames:
        (dataroot / name).unlink(missing_ok=True)
    out = tmp_path / "report"
    assert main(["report", str(synth_points_out), "--out", str(out), "--dataroot", str(dataroot), "--engine",
                 "process", "--workers", "2", "--quiet", "--stills", "2"]) == 0
    err = capsys.readouterr().err
    assert "warning: scene-0002: keyframe renderings: no frame of scene-0002 CAM_FRONT" in err
    assert "scene-0001" not in err
    page = (out / "scenes" / "scene-0002.html").read_text()
    # the video still shows the bird's-eye view, the camera tiles blank; the page says which images are missing
    assert "<video" in page and "camera images missing" in page and any(Path(f).name in page for f in frames)
    assert "no keyframe renderings: no frame of scene-0002" in page
    assert "camera images missing" not in (out / "scenes" / "scene-0001.html").read_text()
    assert len(list((out / "scenes" / "scene-0001").glob("still-*.jpg"))) == 2


def test_real_scenes_local_times_can_bus_and_videos(real_report):
    """The extract's logs are n008-2018-08-30-10-33-52-0400 (Boston) and n015-2018-10-08-15-36-50+0800 (Singapore);
    their scenes start at 14:35:16 and 07:37:13 UTC (first sample timestamps 1535639716699138, 1538984233547259)."""
    rows = {r["scene"]: r for r in rows_of(Page(real_report.index.read_text()).tables["scene-table"])}
    assert (rows["scene-0523"]["local start"], rows["scene-0523"]["time of day"]) == ("10:35", "morning")
    assert (rows["scene-0916"]["local start"], rows["scene-0916"]["time of day"]) == ("15:37", "afternoon")
    assert rows["scene-0916"]["location"] == "singapore-queenstown" and rows["scene-0523"]["samples"] == "40"
    assert {r["CAN bus"] for r in rows.values()} == {"yes"}
    assert {s: v["frames_written"] for s, v in real_report.videos.items()} == {"scene-0523": 40, "scene-0916": 41}
    for scene in rows:
        assert sorted(p.name for p in (real_report.out / "scenes" / scene).iterdir()) == [
            "can_speed.png", "steering.png", "still-0.jpg", "still-1.jpg"]
    assert real_report.problems == {}


def test_cell_text_of_booleans_and_datetimes():
    assert (cell_text(True), cell_text(False)) == ("yes", "no")
    naive = datetime(2018, 8, 30, 14, 35, 16)
    assert cell_text(naive) == "2018-08-30 14:35:16"  # no zone known: none claimed
    assert cell_text(naive.replace(tzinfo=timezone.utc)) == "2018-08-30 14:35:16 UTC"
    boston = datetime(2018, 8, 30, 10, 35, 16, tzinfo=timezone(timedelta(hours=-4)))  # the same instant, EDT
    assert cell_text(boston) == "2018-08-30 14:35:16 UTC"


def test_table_cells_are_escaped_as_text():
    import polars as pl

    from nuparquet.site.html import table

    html = table(pl.DataFrame({"description": ["night, <rain> & fog"], "n": [3]}))
    assert '">night, &lt;rain&gt; &amp; fog</td>' in html and "<rain>" not in html
    assert '<td class="num" data-sort="3">3</td>' in html


def test_keyframe_renderings_draw_the_reference_lidar_when_the_dataset_has_one(synth_points_out, tmp_path):
    """The dataset has LIDAR_TOP: each still is the one-scene renderer's frame of the default camera with the
    lidar's points drawn (`render --lidar`), not the frame without them. (A report of its own, in this test's
    process: the session's report is built during another test.)"""
    import numpy as np

    from nuparquet.rendering.video.options import RenderOptions
    from nuparquet.rendering.video.pipeline import render
    from nuparquet.site.scene_assets import STILL_SCALE

    scene = SCENES[1]
    result = build_report(synth_points_out, SceneSelection(scenes=(scene,)), tmp_path / "report", ReportOptions(stills=2))
    assert len(result.assets[scene]["stills"]) == 2
    frames = {}
    for lidar in (True, False):
        folder = tmp_path / f"lidar-{lidar}"
        render(synth_points_out, scene, None, RenderOptions(channel="CAM_FRONT", lidar=lidar, scale=STILL_SCALE,
                                                            frame_format="jpg"), frames_dir=folder)
        frames[lidar] = sorted(folder.glob("*.jpg"))
    for file, index, count in result.assets[scene]["stills"]:
        assert count == len(frames[True])
        still = cv2.imread(str(result.out / "scenes" / scene / file)).astype(int)
        with_points = cv2.imread(str(frames[True][index])).astype(int)
        without = cv2.imread(str(frames[False][index])).astype(int)
        assert np.abs(still - with_points).max() == 0
        assert (np.abs(still - without).max(axis=2) > 40).sum() > 100  # the points: many pixels, not JPEG noise


def test_the_report_says_its_steps_as_it_goes(synth_points_out, tmp_path):
    """The report's own progress task names each of its five steps as it starts it, in order (the CLI shows the
    step beside the bar)."""
    events = []
    build_report(synth_points_out, SceneSelection(scenes=("scene-0002",)), tmp_path / "report",
                 ReportOptions(videos=False), on_progress=events.append)
    steps = [(e.done, e.total, e.step) for e in events if e.task == "report" and e.step]
    assert steps == [(1, 5, "statistics"), (2, 5, "videos"), (3, 5, "scene assets"), (4, 5, "pages"),
                     (5, 5, "done")]


def test_stills_of_a_scene_with_fewer_keyframes_than_asked_are_every_keyframe():
    from nuparquet.site.scene_assets import evenly_spaced

    assert evenly_spaced(3, 4) == [0, 1, 2] and evenly_spaced(4, 4) == [0, 1, 2, 3] and evenly_spaced(0, 4) == []
    assert evenly_spaced(10, 4) == [0, 3, 6, 9]  # round(k * 9 / 3)
