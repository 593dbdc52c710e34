"""HTML pieces of the report: a page frame, tables from polars DataFrames, fact lists. Every value is escaped;
pages link only to files inside the report folder (relative URLs), so they open from disk with no network."""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Callable, Iterable
from html import escape

import polars as pl


def esc(value) -> str:
    return escape(str(value), quote=True)


def page(title: str, body: str, *, root: str = "", subtitle: str = "") -> str:
    """A whole HTML document; `root` is the relative path from the page to the report folder ("" or "../")."""
    sub = f"<p>{subtitle}</p>" if subtitle else ""
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n<title>{esc(title)}</title>\n'
            f'<link rel="icon" href="data:,">\n'
            f'<link rel="stylesheet" href="{root}assets/report.css">\n'
            f'<script src="{root}assets/report.js" defer></script>\n</head>\n<body>\n'
            f"<header><h1>{esc(title)}</h1>{sub}</header>\n<main>\n{body}\n</main>\n</body>\n</html>\n")


def cell_text(value, decimals: int = 2) -> str:
    """A value as table text: floats with `decimals`, datetimes as ISO text (aware ones in UTC), lists as comma
    lists, None as ""."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return str(value) if math.isnan(value) or math.isinf(value) else f"{value:,.{decimals}f}"
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, dt.datetime):
        if value.tzinfo:  # labelled UTC below: an aware time in another zone is converted, not relabelled
            value = value.astimezone(dt.timezone.utc)
        return value.strftime("%Y-%m-%d %H:%M:%S") + (" UTC" if value.tzinfo else "")
    if isinstance(value, (list, tuple)):
        return ", ".join(cell_text(v, decimals) for v in value)
    return str(value)


def _sort_key(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, (int, float)) and not (isinstance(value, float) and math.isnan(value)):
        return repr(value)
    return str(value)


def table(df: pl.DataFrame, *, max_rows: int | None = None, css: str = "", table_id: str = "",
          links: dict[str, Callable[[object], str]] | None = None, row_data: str | None = None) -> str:
    """`df` as an HTML table. Numeric columns right-aligned; every cell carries `data-sort` (its raw value) so
    sorting is numeric where it should be. `links`: column -> the URL of a value; `row_data`: a column
    whose value goes into each row's `data-location` (for the location filter)."""
    links = links or {}
    numeric = {name: dtype.is_numeric() for name, dtype in df.schema.items()}
    shown = df.head(max_rows) if max_rows is not None else df
    head = "".join(f'<th class="num">{esc(n)}</th>' if numeric[n] else f"<th>{esc(n)}</th>" for n in df.columns)
    rows = []
    for record in shown.iter_rows(named=True):
        cells = []
        for name, value in record.items():
            text = esc(cell_text(value))
            if name in links and value is not None:
                text = f'<a href="{esc(links[name](value))}">{text}</a>'
            css_class = ' class="num"' if numeric[name] else ""
            cells.append(f'<td{css_class} data-sort="{esc(_sort_key(value))}">{text}</td>')
        data = f' data-location="{esc(record[row_data])}"' if row_data else ""
        rows.append(f"<tr{data}>{''.join(cells)}</tr>")
    more = (f'<p class="muted">{df.height - shown.height:,} more rows not shown</p>'
            if shown.height < df.height else "")
    attributes = (f' class="{css}"' if css else "") + (f' id="{table_id}"' if table_id else "")
    return (f'<div class="scroll"><table{attributes}><thead><tr>{head}</tr></thead>\n<tbody>\n' + "\n".join(rows)
            + f"\n</tbody></table></div>{more}")


def facts(pairs: Iterable[tuple[str, str]]) -> str:
    rows = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in pairs)
    return f'<table class="facts">{rows}</table>'
