"""The report in a real browser: headless Chromium (Debian's /usr/bin/chromium, driven by Playwright; no browser
is downloaded) opens every page from disk with no console error and no failed or network request, sorts and
filters the scene table, plays every video (readyState >= 2, the duration of its keyframes, a picture that is not
blank) and writes a screenshot of each page kind (NUPARQUET_SCREENSHOTS names the folder; else a temporary one,
named in the test's report properties and output)."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from nuparquet.engine import unit_file_name

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
VIDEO_STATES = """() => Array.from(document.querySelectorAll('video')).map(v => ({
    state: v.readyState, duration: v.duration, width: v.videoWidth, height: v.videoHeight,
    error: v.error ? v.error.code : null}))"""


@pytest.fixture(scope="module")
def browser(chromium, tmp_path_factory):
    """A Chromium context with a fresh profile, shared by this module's tests."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")), executable_path=str(chromium), headless=True,
            args=CHROMIUM_ARGS, viewport={"width": 1400, "height": 1000})
        yield context
        context.close()


@pytest.fixture(scope="module")
def screenshots(tmp_path_factory) -> Path:
    folder = Path(os.environ["NUPARQUET_SCREENSHOTS"]) if os.environ.get("NUPARQUET_SCREENSHOTS") else \
        tmp_path_factory.mktemp("screenshots")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def visit(browser, path: Path):
    """Open `path` and return (page, problems): console errors and warnings, page errors, failed requests and
    any request that is not to a file (the report must need no network)."""
    problems: list[str] = []
    page = browser.new_page()
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type in ("error", "warning")
            else None)
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.on("requestfailed", lambda r: problems.append(f"failed request {r.url}: {r.failure}"))
    page.on("request", lambda r: None if r.url.startswith(("file:", "data:")) else problems.append(
        f"network request {r.url}"))
    page.goto(path.as_uri(), wait_until="load")
    page.wait_for_load_state("networkidle")
    return page, problems


def scene_pages(result) -> list[Path]:
    return [result.out / "scenes" / f"{unit_file_name(s)}.html" for s in result.scenes]


def test_every_page_loads_with_no_console_error_and_no_failed_request(browser, synth_report, six_scene_report):
    result, _ = synth_report
    for path in [result.index, *scene_pages(result), six_scene_report.index, *scene_pages(six_scene_report)]:
        page, problems = visit(browser, path)
        images = page.evaluate("Array.from(document.images).map(i => [i.getAttribute('src'), i.naturalWidth])")
        page.close()
        assert problems == [], path
        assert all(width > 0 for _, width in images), images  # every chart and still decoded
    assert len(images) >= 0


def _column(page, header: str) -> list[str]:
    index = page.evaluate(f"""Array.from(document.querySelectorAll('#scene-table thead th'))
                              .findIndex(th => th.textContent.trim() === {header!r})""")
    assert index >= 0, header
    return page.evaluate(f"""Array.from(document.querySelectorAll('#scene-table tbody tr'))
                             .filter(tr => !tr.hidden).map(tr => tr.cells[{index}].textContent.trim())""")


def test_the_scene_table_sorts_and_filters(browser, six_scene_report):
    page, problems = visit(browser, six_scene_report.index)
    names = _column(page, "scene")
    assert len(names) == 6 and names == sorted(names)
    page.click("#scene-table th:text-is('annotations')")
    counts = [int(v.replace(",", "")) for v in _column(page, "annotations")]
    assert counts == sorted(counts) and len(set(counts)) > 1
    assert page.get_attribute("#scene-table th:text-is('annotations')", "aria-sort") == "ascending"
    page.click("#scene-table th:text-is('annotations')")
    assert [int(v.replace(",", "")) for v in _column(page, "annotations")] == sorted(counts, reverse=True)
    page.click("#scene-table th:text-is('location')")
    locations = _column(page, "location")
    assert locations == sorted(locations) and len(set(locations)) > 1
    page.click("#scene-table th:text-is('scene')")
    page.click("#scene-table th:text-is('scene')")
    assert _column(page, "scene") == sorted(names, reverse=True)

    page.select_option("#location-filter", locations[0])
    shown = _column(page, "location")
    assert shown == [locations[0]] * locations.count(locations[0])
    assert page.inner_text("#scene-count") == str(len(shown))
    page.select_option("#location-filter", "")
    page.fill("#scene-filter", names[2])
    assert _column(page, "scene") == [names[2]] and page.inner_text("#scene-count") == "1"
    page.fill("#scene-filter", "")
    assert len(_column(page, "scene")) == 6
    page.close()
    assert problems == []


def _check_videos(browser, result, expected_s: dict[str, float]) -> int:
    checked = 0
    for scene, path in zip(result.scenes, scene_pages(result)):
        page, problems = visit(browser, path)
        page.wait_for_function("() => Array.from(document.querySelectorAll('video')).every(v => v.readyState >= 2)",
                               timeout=30_000)
        (video,) = page.evaluate(VIDEO_STATES)
        assert video["error"] is None and video["state"] >= 2, (scene, video)
        assert video["duration"] == pytest.approx(expected_s[scene], abs=0.01), scene
        assert (video["width"], video["height"]) == (result.videos[scene]["width"], result.videos[scene]["height"])
        picture = cv2.imdecode(np.frombuffer(page.locator("video").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert picture.std() > 10, scene  # a decoded picture, not a black or blank box
        page.close()
        assert problems == [], scene
        checked += 1
    return checked


def test_every_video_plays_with_the_duration_of_its_keyframes(browser, synth_report, synth_root):
    import json

    result, _ = synth_report
    samples = json.loads((synth_root / "v1.0-synth" / "sample.json").read_text())
    scenes = {s["token"]: s["name"] for s in json.loads((synth_root / "v1.0-synth" / "scene.json").read_text())}
    keyframes = {name: sum(1 for s in samples if scenes[s["scene_token"]] == name) for name in scenes.values()}
    assert _check_videos(browser, result, {s: keyframes[s] / 2 for s in result.scenes}) == 2


def test_real_scene_videos_play(browser, real_report, extract_root):
    # scene-0523 has 40 keyframes, scene-0916 41 (the extract's README); 2 per second
    assert _check_videos(browser, real_report, {"scene-0523": 20.0, "scene-0916": 20.5}) == 2


def test_a_screenshot_of_each_page_kind(browser, synth_report, real_report, screenshots, record_property, capsys):
    result, _ = synth_report
    shots = {"index": result.index, "scene": scene_pages(result)[0], "real-index": real_report.index,
             "real-scene": scene_pages(real_report)[1]}
    for name, path in shots.items():
        page, problems = visit(browser, path)
        page.wait_for_function("() => Array.from(document.querySelectorAll('video')).every(v => v.readyState >= 2)",
                               timeout=30_000)
        # show a picture from the middle of each video, once Chromium's loading spinner is gone (cosmetic)
        page.evaluate("() => document.querySelectorAll('video').forEach(v => { v.currentTime = v.duration / 2; })")
        page.wait_for_function("""() => Array.from(document.querySelectorAll('video'))
                                  .every(v => !v.seeking && v.readyState >= 2 && v.currentTime > 0)""")
        page.wait_for_timeout(800)
        target = screenshots / f"report-{name}.png"
        page.screenshot(path=str(target), full_page=name.endswith("scene"))
        page.close()
        assert problems == []
        image = cv2.imread(str(target))
        assert image is not None and image.shape[1] == 1400 and image.std() > 10
        record_property(f"screenshot_{name}", str(target))
    with capsys.disabled():
        print(f"\nreport screenshots: {screenshots}")
