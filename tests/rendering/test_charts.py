"""The PNG charts of `nuparquet stats --plots` (`nuparquet.rendering.pictures.charts`), drawn in this process and read back
from the matplotlib figure: what each bar and line shows, against the chart's input counted in plain Python."""

from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np
import polars as pl
import pytest

import nuparquet
from nuparquet.rendering.pictures import charts


@pytest.fixture
def figures(monkeypatch):
    """The figures the charts save (kept after `_save` closes them)."""
    kept = []
    saved = charts._save
    monkeypatch.setattr(charts, "_save", lambda fig, path: (kept.append(fig), saved(fig, path))[1])
    return kept


def test_can_speed_draws_the_scenes_own_rows_of_each_source(synth_out, tmp_path, figures):
    """Each source's line is that scene's rows with a speed, in time order, and nothing of the other scenes (the
    synthetic CAN bus covers every scene but the last: the last has its ego-pose speeds only)."""
    from nuparquet.queries.can_bus import speed_over_time

    speeds = speed_over_time(nuparquet.open(synth_out)).collect()
    scenes = sorted(set(speeds["scene_name"].to_list()))
    assert len(scenes) == 2
    label_of = {"pose": "CAN pose |vel|", "vehicle_monitor": "CAN vehicle_monitor", "ego_pose": "ego pose"}
    for scene, sources in zip(scenes, (["pose", "vehicle_monitor", "ego_pose"], ["ego_pose"])):
        charts.plot_can_speed(speeds, tmp_path / f"{scene}.png", scene=scene)
        lines = figures[-1].axes[0].get_lines()
        assert len(lines) == len(sources)
        for source in sources:
            rows = sorted((r["time_s"], r["speed_mps"]) for r in speeds.to_dicts()
                          if r["scene_name"] == scene and r["source"] == source and r["speed_mps"] is not None)
            line = next(line for line in lines if line.get_label().startswith(label_of[source]))
            assert len(rows) > 3
            assert np.array_equal(np.c_[line.get_xdata(), line.get_ydata()], np.array(rows))


def test_distance_histogram_stacks_the_counts_of_each_category_in_its_colour(tmp_path, figures):
    """Eleven categories: the nine most frequent (ties by name) in tab10's colours but its grey, in that order; the
    other two summed into a grey "other"; bars stacked bin by bin."""
    rows = []
    for k in range(11):  # category ck: 30 - 2k annotations in all, over the bins of 0, 10 and 20 m
        total = 30 - 2 * k if k != 4 else 24  # c03 and c04 tie at 24: c03 first, by name
        for start, share in ((0.0, 0.5), (10.0, 0.3), (20.0, 0.2)):
            count = round(total * share) if start < 20 else total - round(total * 0.5) - round(total * 0.3)
            if count:
                rows.append({"category_name": f"c{k:02d}", "bin_start_m": start, "bin_end_m": start + 10.0,
                             "count": count})
    histogram = pl.DataFrame(rows)
    charts.plot_distance_histogram(histogram, tmp_path / "distance.png")
    bars = figures[-1].axes[0].containers
    totals = {}
    for r in rows:
        totals[r["category_name"]] = totals.get(r["category_name"], 0) + r["count"]
    top = sorted(totals, key=lambda name: (-totals[name], name))[:9]
    assert top[3:5] == ["c03", "c04"] and totals["c03"] == totals["c04"]
    assert [b.get_label() for b in bars] == top + ["other"]
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
               "tab:cyan", "0.6"]
    starts = [0.0, 10.0, 20.0]
    bottom = np.zeros(3)
    for bar, colour in zip(bars, colours):
        group = [bar.get_label()] if bar.get_label() != "other" else [n for n in totals if n not in top]
        expected = [sum(r["count"] for r in rows if r["category_name"] in group and r["bin_start_m"] == s)
                    for s in starts]
        assert [p.get_x() for p in bar.patches] == starts and all(p.get_width() == 10.0 for p in bar.patches)
        assert [p.get_height() for p in bar.patches] == expected
        assert np.array_equal([p.get_y() for p in bar.patches], bottom)
        assert all(np.allclose(p.get_facecolor(), mcolors.to_rgba(colour)) for p in bar.patches)
        bottom += expected
    assert len(bars[-1].patches) == 3 and sum(p.get_height() for p in bars[-1].patches) == totals["c09"] + totals["c10"]


def test_class_distribution_bars_and_labels_are_each_categorys_counts(tmp_path, figures):
    """Categories from the fewest annotations up: an annotations bar over an instances bar per category, each
    annotations bar labelled with its count at its end, the categories named on the y axis."""
    distribution = pl.DataFrame({"category_name": ["car", "pedestrian", "barrier", "bus"],
                                 "num_annotations": [1200, 45, 300, 7], "num_instances": [80, 9, 12, 1]})
    charts.plot_class_distribution(distribution, tmp_path / "classes.png")
    ax = figures[-1].axes[0]
    order = sorted(distribution.to_dicts(), key=lambda r: r["num_annotations"])
    annotations, instances = ax.containers
    assert [p.get_width() for p in annotations.patches] == [r["num_annotations"] for r in order]
    assert [p.get_width() for p in instances.patches] == [r["num_instances"] for r in order]
    assert [round(p.get_y() + p.get_height() / 2, 6) for p in annotations.patches] == [y + 0.2 for y in range(4)]
    assert [t.get_text() for t in ax.get_yticklabels()] == [r["category_name"] for r in order]
    labels = [(t.get_position(), t.get_text()) for t in ax.texts]
    assert labels == [((r["num_annotations"], y + 0.2), f" {r['num_annotations']:,}") for y, r in enumerate(order)]


def test_points_per_box_prints_each_categorys_share_of_empty_boxes_above_its_box(tmp_path, figures):
    """One box per category (by name), whiskers at p5/p95, box p25-p75, median line; above each box, centred on it
    and above the highest whisker, the share of its boxes with no point, as a whole percentage."""
    rows = [("vehicle.car", [0, 1, 3, 8, 20, 55], 5.0, 0.25), ("human.pedestrian.adult", [0, 0, 0, 2, 4, 9], 1.5, 0.5),
            ("movable_object.barrier", [2, 4, 6, 9, 14, 30], 8.0, 0.0)]
    stats = {"category_name": [name for name, *_ in rows]}
    for k, key in enumerate(("p05", "p25", "p50", "p75", "p95", "max")):
        stats[f"lidar_{key}"] = [float(p[k]) for _, p, _, _ in rows]
    stats["lidar_mean"] = [mean for _, _, mean, _ in rows]
    stats["lidar_zero_share"] = [share for *_, share in rows]
    charts.plot_points_per_box(pl.DataFrame(stats), tmp_path / "points.png")
    ax = figures[-1].axes[0]
    by_name = sorted(rows)
    assert [t.get_text() for t in ax.get_xticklabels()] == [name for name, *_ in by_name]
    top = max(p[4] for _, p, _, _ in rows)  # the highest p95
    texts = [(t.get_position(), t.get_text(), t.get_horizontalalignment()) for t in ax.texts]
    assert texts == [((x, top * 1.6), f"{round(100 * share)}%", "center")
                     for x, (*_, share) in enumerate(by_name, start=1)]
    assert ax.get_ylim()[1] == top * 3  # room for the shares


def test_lidarseg_counts_without_labelled_points_say_so(tmp_path, figures):
    """Classes with no point are left out; when no class has a point the chart says "no labelled points"."""
    counts = pl.DataFrame({"index": [0, 17], "name": ["noise", "vehicle.car"], "points": [0, 0]})
    charts.plot_lidarseg_counts(counts, tmp_path / "lidarseg.png")
    ax = figures[-1].axes[0]
    assert [t.get_text() for t in ax.texts] == ["no labelled points"] and not ax.patches
