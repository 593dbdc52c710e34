"""PNG charts of the canned query results (matplotlib, Agg backend: no display needed).

Each `plot_*` function takes the collected result of one query in `nuparquet.queries` and writes one PNG;
`write_plots(ds, out_dir)` runs the queries and writes them all.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless; must precede pyplot

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import polars as pl  # noqa: E402

from nuparquet import queries  # noqa: E402

DPI = 110
MAX_CATEGORIES = 9  # distance histogram: the most frequent categories, the rest as "other"
MAX_SCENES = 12  # ego speed: curves drawn (the first scenes by name)


def _save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _empty(ax, what: str) -> None:
    ax.text(0.5, 0.5, f"no {what}", ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()


def plot_class_distribution(distribution: pl.DataFrame, path: Path, *, title: str = "Class distribution") -> Path:
    """Horizontal bars of annotations and instances per category (log scale), from `class_distribution`."""
    data = distribution.sort("num_annotations")
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.32 * max(data.height, 1)), layout="constrained")
    if data.is_empty():
        _empty(ax, "annotations")
        return _save(fig, path)
    y = np.arange(data.height)
    ax.barh(y + 0.2, data["num_annotations"], height=0.4, label="annotations", color="tab:blue")
    ax.barh(y - 0.2, data["num_instances"], height=0.4, label="instances (tracks)", color="tab:orange")
    for yi, n in zip(y, data["num_annotations"]):
        ax.text(n, yi + 0.2, f" {n:,}", va="center", fontsize=7)
    ax.set_yticks(y, data["category_name"].to_list(), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlim(0.7, float(data["num_annotations"].max()) * 2.5)  # room for the labels
    ax.set_xlabel("count (log scale)")
    ax.set_title(title)
    ax.legend(loc="lower right")
    return _save(fig, path)


def plot_distance_histogram(histogram: pl.DataFrame, path: Path, *, title: str = "Distance to ego vehicle",
                            max_categories: int = MAX_CATEGORIES) -> Path:
    """Stacked bars of annotation counts per distance bin, one colour per category, from `distance_histogram`."""
    fig, ax = plt.subplots(figsize=(10, 5.5), layout="constrained")
    if histogram.is_empty():
        _empty(ax, "annotations with a distance")
        return _save(fig, path)
    totals = histogram.group_by("category_name").agg(pl.col("count").sum()).sort(["count", "category_name"],
                                                                                 descending=[True, False])
    top = totals["category_name"].head(max_categories).to_list()
    data = histogram.with_columns(
        pl.when(pl.col("category_name").is_in(top)).then(pl.col("category_name")).otherwise(pl.lit("other"))
        .alias("group"))
    groups = top + (["other"] if totals.height > len(top) else [])
    starts = np.sort(data["bin_start_m"].unique().to_numpy())
    width = float((data["bin_end_m"] - data["bin_start_m"]).first())
    bottom = np.zeros(len(starts))
    palette = [c for i, c in enumerate(plt.get_cmap("tab10").colors) if i != 7]  # tab10 without its grey
    for i, group in enumerate(groups):
        counts = (data.filter(pl.col("group") == group).group_by("bin_start_m").agg(pl.col("count").sum()))
        heights = np.zeros(len(starts))
        heights[np.searchsorted(starts, counts["bin_start_m"].to_numpy())] = counts["count"].to_numpy()
        ax.bar(starts, heights, width=width, bottom=bottom, align="edge", label=group,
               color="0.6" if group == "other" else palette[i % len(palette)],
               edgecolor="white", linewidth=0.3)
        bottom += heights
    ax.set_xlabel("xy distance from the ego vehicle (m)")
    ax.set_ylabel("annotations")
    ax.set_title(title)
    ax.legend(fontsize=7, ncols=2)
    return _save(fig, path)


def plot_points_per_box(points: pl.DataFrame, path: Path, *, sensor: str = "lidar",
                        title: str | None = None) -> Path:
    """Box plot of points per box by category from `points_per_box` statistics.

    Boxes span the 25th-75th percentile with the median line; whiskers reach the 5th and 95th percentiles.
    Symmetric-log y axis, so empty boxes (0 points) stay visible; the share of empty boxes is printed on top.
    """
    data = points.sort("category_name")
    fig, ax = plt.subplots(figsize=(max(6, 0.55 * data.height + 2), 6), layout="constrained")
    if data.is_empty():
        _empty(ax, "annotations")
        return _save(fig, path)
    stats = [
        {"label": name, "med": row[f"{sensor}_p50"], "q1": row[f"{sensor}_p25"], "q3": row[f"{sensor}_p75"],
         "whislo": row[f"{sensor}_p05"], "whishi": row[f"{sensor}_p95"], "mean": row[f"{sensor}_mean"]}
        for name, row in zip(data["category_name"], data.iter_rows(named=True))
    ]
    ax.bxp(stats, showfliers=False, showmeans=True, patch_artist=True,
           boxprops={"facecolor": "tab:blue", "alpha": 0.5})
    ax.set_yscale("symlog", linthresh=1)
    top = max(1.0, float(data[f"{sensor}_p95"].max()))
    for x, share in enumerate(data[f"{sensor}_zero_share"], start=1):
        ax.text(x, top * 1.6, f"{share:.0%}", ha="center", fontsize=7, color="tab:red")
    ax.set_ylim(-0.2, top * 3)
    ax.set_xticks(range(1, data.height + 1), data["category_name"].to_list(), rotation=60, ha="right", fontsize=8)
    ax.set_ylabel(f"{sensor} points per box (symlog)")
    ax.set_title(title or f"{sensor.capitalize()} points per box (box: p25-p75, whiskers: p5-p95, "
                          "triangle: mean; red: share of boxes with 0 points)", fontsize=9)
    return _save(fig, path)


def plot_ego_speed(motion: pl.DataFrame, path: Path, *, max_scenes: int = MAX_SCENES,
                   title: str = "Ego speed (reference lidar keyframes)") -> Path:
    """Ego speed over time, one line per scene (the first `max_scenes` scenes by name), from `ego_motion`."""
    fig, ax = plt.subplots(figsize=(10, 5), layout="constrained")
    scenes = sorted(motion["scene_name"].unique().to_list())
    if not scenes:
        _empty(ax, "reference lidar keyframes")
        return _save(fig, path)
    shown = scenes[:max_scenes]
    if len(shown) > 10:
        ax.set_prop_cycle(color=plt.get_cmap("tab20").colors)  # distinct colours beyond ten lines
    for scene_name in shown:
        rows = motion.filter(pl.col("scene_name") == scene_name).sort("time_s")
        ax.plot(rows["time_s"], rows["speed_mps"], marker=".", markersize=3, linewidth=1, label=scene_name)
    ax.set_xlabel("time since the scene's first keyframe (s)")
    ax.set_ylabel("speed (m/s)")
    ax.set_ylim(bottom=0)
    suffix = f" — first {len(shown)} of {len(scenes)} scenes" if len(shown) < len(scenes) else ""
    ax.set_title(title + suffix)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncols=2 if len(shown) > 6 else 1)
    return _save(fig, path)


def plot_can_speed(speeds: pl.DataFrame, path: Path, *, scene: str) -> Path:
    """Speed over time of one scene from the CAN bus (vehicle_monitor vehicle speed, pose |vel|) and from the ego
    poses (`queries.can_bus.speed_over_time`)."""
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    rows = speeds.filter(pl.col("scene_name") == scene)
    styles = {"pose": ("CAN pose |vel| (50 Hz)", "-", None), "vehicle_monitor": ("CAN vehicle_monitor vehicle_speed (2 Hz)", "-", "o"),
              "ego_pose": ("ego pose, reference lidar keyframes (2 Hz)", "--", "x")}
    for source, (label, line, marker) in styles.items():
        part = rows.filter(pl.col("source") == source).drop_nulls("speed_mps")
        if part.height:
            ax.plot(part["time_s"], part["speed_mps"], line, marker=marker, markersize=4, linewidth=1.2, label=label)
    if rows.is_empty():
        _empty(ax, "CAN bus messages")
    else:
        ax.set_xlabel("time since the scene's first sample (s)")
        ax.set_ylabel("speed (m/s)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    ax.set_title(f"Speed: CAN bus vs ego pose — {scene}")
    return _save(fig, path)


def plot_steering(steering: pl.DataFrame, path: Path, *, scene: str) -> Path:
    """Steering wheel angle and yaw rate over time of one scene (`queries.can_bus.steering_over_time`)."""
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    rows = steering.filter(pl.col("scene_name") == scene)
    steer = rows.filter(pl.col("source") == "steering_rad")
    yaw = rows.filter(pl.col("source") == "yaw_rate_radps")
    if rows.is_empty():
        _empty(ax, "CAN bus messages")
    else:
        ax.plot(steer["time_s"], steer["value"], linewidth=1.2, label="steering wheel angle (rad)")
        ax.set_xlabel("time since the scene's first sample (s)")
        ax.set_ylabel("steering wheel angle (rad)")
        twin = ax.twinx()
        twin.plot(yaw["time_s"], yaw["value"], color="tab:orange", linewidth=1, label="yaw rate (rad/s)")
        twin.set_ylabel("yaw rate (rad/s)")
        ax.grid(alpha=0.3)
        fig.legend(loc="upper right", fontsize=8)
    ax.set_title(f"Steering and yaw rate (CAN bus) — {scene}")
    return _save(fig, path)


def plot_lidarseg_counts(counts: pl.DataFrame, path: Path, *, title: str = "Lidar points per class") -> Path:
    """Horizontal bars of labelled lidar points per class (log scale, classes without points left out), from
    `queries.points.lidarseg_class_counts`; bars in the category colours."""
    from nuparquet.rendering.palette import category_rgb

    data = counts.filter(pl.col("points") > 0).sort("points")
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.32 * max(data.height, 1)), layout="constrained")
    if data.is_empty():
        _empty(ax, "labelled points")
        return _save(fig, path)
    y = np.arange(data.height)
    colours = [tuple(c / 255 for c in category_rgb(name)) for name in data["name"].to_list()]
    ax.barh(y, data["points"], color=colours, edgecolor="0.3", linewidth=0.4)
    total = int(data["points"].sum())
    for yi, n in zip(y, data["points"]):
        ax.text(n, yi, f" {n:,} ({100 * n / total:.1f}%)", va="center", fontsize=7)
    ax.set_yticks(y, [f"{i:>2} {n}" for i, n in zip(data["index"], data["name"])], fontsize=8)
    ax.set_xscale("log")
    ax.set_xlim(0.7, float(data["points"].max()) * 6)
    ax.set_xlabel("points (log scale)")
    ax.set_title(title)
    return _save(fig, path)


def write_plots(ds, out_dir: Path, *, scene: str | Sequence[str] | None = None,
                results: dict[str, pl.DataFrame] | None = None) -> list[Path]:
    """Write the charts of `nuparquet stats --plots` into `out_dir` (four, and two more from the CAN bus when it
    was converted); returns their paths.

    `results` may hold already collected `queries.summary` sections (``class_distribution``,
    ``distance_histogram``, ``points_per_box``, ``ego_motion``) to avoid running them again.
    """
    results = dict(results or {})
    needed = [s for s in ("class_distribution", "distance_histogram", "points_per_box", "ego_motion")
              if s not in results]
    if needed:
        lazy = queries.summary(ds, scene=scene, sections=needed)
        results.update(zip(lazy, pl.collect_all(list(lazy.values()))))
    out_dir = Path(out_dir)
    where = f" — {scene}" if isinstance(scene, str) else ""
    return [
        plot_class_distribution(results["class_distribution"], out_dir / "class_distribution.png",
                                title=f"Annotations and instances per category{where}"),
        plot_distance_histogram(results["distance_histogram"], out_dir / "distance_histogram.png",
                                title=f"Distance from the ego vehicle by category{where}"),
        plot_points_per_box(results["points_per_box"], out_dir / "lidar_points_per_box.png"),
        plot_ego_speed(results["ego_motion"], out_dir / "ego_speed.png"),
        *_can_bus_plots(ds, out_dir, scene),
        *_lidarseg_plots(ds, out_dir, scene),
    ]


def _lidarseg_plots(ds, out_dir: Path, scene) -> list[Path]:
    """lidarseg_points_per_class.png when lidar_points/ holds lidarseg labels."""
    from nuparquet.queries import points

    if "lidar_points" not in ds.datasets or not points.has_labels(ds, "lidarseg"):
        return []
    where = f" — {scene}" if isinstance(scene, str) else ""
    counts = points.lidarseg_class_counts(ds, scene=scene).collect()
    return [plot_lidarseg_counts(counts, out_dir / "lidarseg_points_per_class.png",
                                 title=f"nuScenes-lidarseg: labelled lidar points per class{where}")]


def _can_bus_plots(ds, out_dir: Path, scene) -> list[Path]:
    """can_speed.png and steering.png for one scene (the one asked for, else the first with CAN bus data), when
    the output has the CAN bus datasets."""
    from nuparquet.queries import can_bus

    if not {"can_bus/vehicle_monitor", "can_bus/pose", "can_bus/steeranglefeedback"} <= set(ds.datasets):
        return []
    if scene is None or not isinstance(scene, str):
        names = ds.scan("can_bus/pose").select(pl.col("scene_name").unique().sort()).collect()["scene_name"].to_list()
        candidates = [n for n in names if scene is None or n in scene]
        if not candidates:
            return []
        scene = candidates[0]
    speeds, steering = pl.collect_all([can_bus.speed_over_time(ds, scene=scene), can_bus.steering_over_time(ds, scene=scene)])
    return [plot_can_speed(speeds, out_dir / "can_speed.png", scene=scene),
            plot_steering(steering, out_dir / "steering.png", scene=scene)]
