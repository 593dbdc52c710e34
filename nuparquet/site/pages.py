"""The report's two kinds of page: the index (dataset facts, statistics tables and charts, the scene table) and one
page per scene (facts, video, keyframe renderings, CAN bus plots, categories)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from urllib.parse import quote

import polars as pl

from nuparquet.site import html
from nuparquet.site.html import esc

SCENE_COLUMNS = {  # scene table column -> header
    "name": "scene", "log_location": "location", "date_captured": "date", "local_start": "local start",
    "time_of_day": "time of day", "weather": "weather / light", "duration_s": "duration s",
    "nbr_samples": "samples", "num_annotations": "annotations", "num_instances": "instances",
    "ego_distance_m": "ego distance m", "can_bus": "CAN bus", "description": "description",
}


def scene_href(name: str) -> str:
    """The page of a scene, relative to the report folder (the name quoted like the videos' file names)."""
    from nuparquet.engine import unit_file_name

    return f"scenes/{quote(unit_file_name(name))}.html"


def index_page(title: str, facts: Sequence[tuple[str, str]], sections: Sequence[tuple[str, str, pl.DataFrame]],
               charts: Sequence[tuple[str, str]], scenes: pl.DataFrame, *, max_rows: int, note: str = "") -> str:
    """sections: (name, title, result); charts: (relative path, caption)."""
    locations = sorted(set(scenes["log_location"].drop_nulls().to_list()))
    options = "".join(f'<option value="{esc(loc)}">{esc(loc)}</option>' for loc in locations)
    table = scenes.select(list(SCENE_COLUMNS)).rename(SCENE_COLUMNS)
    body = [
        "<h2>Dataset</h2>", html.facts(facts),
        f'<p class="muted">{esc(note)}</p>' if note else "",
        f'<h2 id="scenes">Scenes (<span id="scene-count">{scenes.height}</span> of {scenes.height} shown)</h2>',
        '<div class="controls"><input id="scene-filter" type="search" placeholder="filter: words of any column" '
        'aria-label="filter scenes">'
        f'<select id="location-filter" aria-label="location"><option value="">every location</option>{options}'
        "</select><span class=\"muted\">click a column header to sort</span></div>",
        html.table(table, css="sortable", table_id="scene-table", links={"scene": scene_href}, row_data="location"),
        "<h2>Charts</h2>",
        '<div class="charts">' + "".join(
            f'<figure><img src="{esc(path)}" alt="{esc(caption)}" loading="lazy"><figcaption>{esc(caption)}'
            "</figcaption></figure>" for path, caption in charts) + "</div>",
        "<h2>Statistics</h2>",
    ]
    for name, section_title, result in sections:
        body.append(f'<details id="{esc(name)}"><summary>{esc(section_title)}</summary>'
                    f'{html.table(result, css="sortable", max_rows=max_rows)}</details>')
    return html.page(title, "\n".join(body), subtitle="nuparquet dataset report")


def scene_page(row: dict, *, video: dict | None, video_error: str | None, stills: Sequence[Sequence],
               stills_error: str | None, plots: Sequence[str], categories: pl.DataFrame, max_rows: int,
               assets: str) -> str:
    """One scene's page. video: its render summary entry ({"video", "frames_written", "fps", ...}) or None;
    stills: [file, keyframe index, keyframes]; `assets`: the scene's folder relative to the page."""
    name = row["name"]
    facts = [("description", row["description"]), ("location", row["log_location"]),
             ("date", row["date_captured"]), ("local start", f"{row['local_start']} ({row['time_zone']})"
                                               if row["local_start"] else "unknown"),
             ("time of day", row["time_of_day"] or "unknown"), ("weather / light words", row["weather"] or "none"),
             ("duration", f"{row['duration_s']:.1f} s"), ("samples (keyframes)", f"{row['nbr_samples']:,}"),
             ("annotations", f"{row['num_annotations']:,}"), ("instances", f"{row['num_instances']:,}"),
             ("ego distance", f"{row['ego_distance_m']:.1f} m")]
    body = ['<p><a href="../index.html">&larr; all scenes</a></p>', html.facts(facts), "<h2>Video</h2>"]
    if video is not None:
        seconds = video["frames_written"] / video["fps"]
        body.append(f'<video id="scene-video" controls muted preload="auto" width="{video["width"]}" '
                    f'src="../videos/{esc(quote(video["video"]))}"></video>'
                    f'<p class="muted">every camera tiled, front row over back row, with the bird\'s-eye view; '
                    f'{video["frames_written"]} keyframes at {video["fps"]:g} fps ({seconds:.1f} s), H.264</p>')
        if video.get("missing"):
            body.append(f'<p class="muted">camera images missing (their tiles are blank), e.g. '
                        f'{esc(", ".join(Path(m).name for m in video["missing"][:3]))}</p>')
    else:
        body.append(f'<p class="muted">no video: {esc(video_error or "not rendered (--no-videos)")}</p>')
    body.append("<h2>Keyframes</h2>")
    if stills:
        body.append('<div class="stills">' + "".join(
            f'<figure><img src="{esc(assets)}/{esc(file)}" alt="keyframe {index + 1} of {count}">'
            f"<figcaption>keyframe {index + 1} of {count}</figcaption></figure>" for file, index, count in stills)
            + "</div>")
    else:
        body.append(f'<p class="muted">no keyframe renderings: {esc(stills_error or "not rendered")}</p>')
    body.append("<h2>CAN bus</h2>")
    if plots:
        body.append('<div class="charts">' + "".join(
            f'<figure><img src="{esc(assets)}/{esc(p)}" alt="{esc(p)}"></figure>' for p in plots) + "</div>")
    else:
        body.append('<p class="muted">no CAN bus messages for this scene</p>')
    body += ["<h2>Categories</h2>", html.table(categories, css="sortable", max_rows=max_rows)]
    return html.page(name, "\n".join(body), root="../", subtitle=esc(row["description"]))
