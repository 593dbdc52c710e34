"""What the report says about a dataset and its scenes, as polars queries over the converted output.

The scene table adds to `queries.scene_summary` what a reader skims for: the local start time and the time of day
(from the log's UTC offset, which nuScenes log names carry, e.g. `n008-2018-08-30-10-33-52-0400`; else from the
location's time zone), the weather and light words of the description, and whether CAN bus data exists.
"""

from __future__ import annotations

import re
from datetime import datetime, timedelta, timezone

import polars as pl

from nuparquet.queries import scene_summary

# Words of nuScenes descriptions that say something about weather or light (matched as word prefixes, any case).
WEATHER_WORDS = ("rain", "drizzle", "wet", "puddle", "fog", "snow", "sun", "cloud", "overcast", "night", "dark",
                 "glare")
# Time zones of the known nuScenes locations, for logs whose names carry no UTC offset.
LOCATION_TIME_ZONES = {"boston-seaport": "America/New_York", "singapore-onenorth": "Asia/Singapore",
                       "singapore-queenstown": "Asia/Singapore", "singapore-hollandvillage": "Asia/Singapore"}
_LOG_OFFSET = re.compile(r"([+-])(\d{2})(\d{2})$")


def log_utc_offset_min(logfile: str | None) -> int | None:
    """Minutes east of UTC from a nuScenes log name ending in +HHMM / -HHMM, else None."""
    found = _LOG_OFFSET.search(logfile or "")
    if found is None:
        return None
    sign = 1 if found.group(1) == "+" else -1
    return sign * (int(found.group(2)) * 60 + int(found.group(3)))


def local_start(timestamp_us: int, logfile: str | None, location: str | None) -> tuple[datetime | None, str]:
    """The local time of `timestamp_us` and the offset or zone it was taken from: the log name's UTC offset, else
    the location's zone (polars' time zone database), else (None, "")."""
    start = datetime(1970, 1, 1, tzinfo=timezone.utc) + timedelta(microseconds=int(timestamp_us))
    offset = log_utc_offset_min(logfile)
    if offset is not None:
        sign = "+" if offset >= 0 else "-"
        zone = f"UTC{sign}{abs(offset) // 60:02d}:{abs(offset) % 60:02d}"
        return start.astimezone(timezone(timedelta(minutes=offset))), zone
    zone = LOCATION_TIME_ZONES.get(location or "")
    if zone is None:
        return None, ""
    local = (pl.Series([int(timestamp_us)]).cast(pl.Datetime("us", "UTC")).dt.convert_time_zone(zone)
             .dt.replace_time_zone(None)[0])
    return local, zone


def time_of_day(hour: int | None, description: str) -> str:
    """night (20:00-06:00, or "night" in the description), morning (6-12), afternoon (12-17), evening (17-20),
    or "" when the local time is unknown."""
    if re.search(r"\bnight", description, re.IGNORECASE):
        return "night"
    if hour is None:
        return ""
    return "night" if hour < 6 or hour >= 20 else "morning" if hour < 12 else "afternoon" if hour < 17 else "evening"


def weather_words(description: str) -> list[str]:
    """The WEATHER_WORDS the description holds (as words or word prefixes: "rainy" -> rain), in list order."""
    words = re.findall(r"[a-z]+", description.lower())
    return [w for w in WEATHER_WORDS if any(word.startswith(w) for word in words)]


def scene_table(dataset, scenes: list[str]) -> pl.DataFrame:
    """One row per scene of `scenes` (sorted by name): name, description, log_location, date_captured,
    local_start ("HH:MM" local time, "" when unknown), time_zone (the offset or zone used), time_of_day,
    weather (comma-separated words), duration_s, nbr_samples, num_annotations, num_instances, ego_distance_m,
    can_bus (bool)."""
    summary = scene_summary(dataset, scene=scenes).collect()
    logs = (dataset.scan("scenes").filter(pl.col("name").is_in(scenes))
            .select("name", "logfile", "first_timestamp").collect())
    summary = summary.join(logs, on="name", how="left")
    can_scenes: set[str] = set()
    if "can_bus/pose" in dataset.datasets:
        can_scenes = set(dataset.scan("can_bus/pose").select(pl.col("scene_name").unique()).collect()["scene_name"])
    rows = []
    for row in summary.sort("name").iter_rows(named=True):
        local, zone = local_start(row["first_timestamp"], row["logfile"], row["log_location"])
        hour = local.hour if local is not None else None
        description = row["description"] or ""
        rows.append({
            "name": row["name"], "description": description, "log_location": row["log_location"],
            "date_captured": row["date_captured"],
            "local_start": local.strftime("%H:%M") if local is not None else "", "time_zone": zone,
            "time_of_day": time_of_day(hour, description), "weather": ", ".join(weather_words(description)),
            "duration_s": row["duration_s"], "nbr_samples": row["nbr_samples"],
            "num_annotations": row["num_annotations"], "num_instances": row["num_instances"],
            "ego_distance_m": row["ego_distance_m"], "can_bus": row["name"] in can_scenes,
        })
    return pl.DataFrame(rows, schema={
        "name": pl.String, "description": pl.String, "log_location": pl.String, "date_captured": pl.String,
        "local_start": pl.String, "time_zone": pl.String, "time_of_day": pl.String, "weather": pl.String,
        "duration_s": pl.Float64, "nbr_samples": pl.Int64, "num_annotations": pl.Int64, "num_instances": pl.Int64,
        "ego_distance_m": pl.Float64, "can_bus": pl.Boolean})


def dataset_facts(dataset) -> list[tuple[str, str]]:
    """(label, value) lines about the dataset: source, version, when converted, sensors, sizes."""
    manifest = dataset.manifest
    source = manifest.get("source", {})
    channels = dataset.channels
    counts = {name: dataset.row_count(name) for name in ("scenes", "frames", "annotations", "instances")
              if name in dataset.datasets}
    samples = dataset.row_count("tables/sample") if "tables/sample" in dataset.datasets else None
    listing = [] if dataset.is_remote else [size for name in dataset.datasets for _, size in dataset.files(name)]
    facts = [
        ("source", str(source.get("dataroot", ""))),
        ("version", str(source.get("version", ""))),
        ("converted", f"{manifest.get('created_utc', '')} by nuparquet {manifest.get('nuparquet_version', '')} "
                      f"(format {manifest.get('format_version', '')})"),
        ("cameras", ", ".join(channels.get("cameras", [])) or "none"),
        ("lidars", ", ".join(channels.get("lidars", [])) or "none"),
        ("radars", ", ".join(channels.get("radars", [])) or "none"),
        ("scenes", f"{counts.get('scenes', 0):,}"),
        ("samples (keyframes)", f"{samples:,}" if samples is not None else ""),
        ("sensor frames", f"{counts.get('frames', 0):,}"),
        ("annotations", f"{counts.get('annotations', 0):,}"),
        ("instances (tracks)", f"{counts.get('instances', 0):,}"),
        ("datasets", f"{len(dataset.datasets)} ({sum(listing) / 1e6:,.1f} MB of Parquet)"),
        ("CAN bus", "converted" if "can_bus/pose" in dataset.datasets else "not converted"),
        ("map", "converted" if "map/lane" in dataset.datasets else "not converted"),
        ("sensor points", ", ".join(n for n in ("lidar_points", "radar_points") if n in dataset.datasets)
         or "not converted"),
    ]
    return facts
