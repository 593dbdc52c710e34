"""Predicted trajectories over the map raster (`nuparquet eval --task prediction --out DIR` draws them into
`DIR/plots/trajectories/*.png`; `write_trajectory_plots(dir, ds, result)` from Python): for an agent, the map around where it stands (drivable area, walkways, crossings and lane dividers, north up, as the map
pictures draw them), its past over `HISTORY_S` seconds (grey), its ground-truth future (black, a dot per step) and
each predicted mode (the matplotlib colour cycle by rank, the most probable first and thickest), named with its
probability and displacement errors.

The agents drawn are those with the largest final error of their most probable mode (`MinFDEK_1`, else the first
metric's k=1 column), the ones worth looking at first; `count` of them (8 by default).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import polars as pl
import shapely

from nuparquet.rendering import legend
from nuparquet.rendering.map_canvas import MapCanvas
from nuparquet.rendering.palette import LINE_CYCLE_RGB

HISTORY_S = 2.0
LAYERS = ("drivable_area", "walkway", "ped_crossing", "lane_divider")
MARGIN_M = 10.0  # around the agent, its past, its future and every mode
MAX_SIDE_M = 200.0  # a mode thrown kilometres away leaves the picture at the agent's scale (drawn to its edge)
PAST_RGB, FUTURE_RGB, AGENT_RGB = (140, 140, 140), (0, 0, 0), (220, 0, 0)
DEFAULT_COUNT = 8


def trajectory_picture(ds, location: str | None, present_xy, past_xy, future_xy, modes_xy, probabilities, *,
                       labels=None, title: str = "", size_px: int = 700) -> np.ndarray:
    """(H, W, 3) uint8 RGB: the agent at `present_xy` (2,), its `past_xy` (P, 2, oldest first), `future_xy` (T, 2) and
    `modes_xy` (M, T', 2) (global metres) over the map of `location` (None: a white ground). `probabilities` (M,)
    rank the modes (ties: the earlier mode first, as the metrics rank them); `labels` (M,) name each mode."""
    from nuparquet.rendering.pictures.map_views import draw_layers

    present = np.asarray(present_xy, dtype=np.float64).reshape(2)
    modes = np.asarray(modes_xy, dtype=np.float64).reshape(-1, np.asarray(modes_xy).shape[-2], 2)
    drawn = np.concatenate([present[None], np.asarray(past_xy, np.float64).reshape(-1, 2),
                            np.asarray(future_xy, np.float64).reshape(-1, 2), modes.reshape(-1, 2)])
    drawn = drawn[np.isfinite(drawn).all(axis=1)]
    low, high = drawn.min(axis=0) - MARGIN_M, drawn.max(axis=0) + MARGIN_M
    side = max(high - low)  # square: the same metres per pixel both ways, the agent's surroundings in view
    centre = (low + high) / 2
    if side > MAX_SIDE_M:
        side, centre = MAX_SIDE_M, present
    canvas = MapCanvas.create((centre[0] - side / 2, centre[1] - side / 2, centre[0] + side / 2,
                               centre[1] + side / 2), size_px)
    if location is not None:
        draw_layers(canvas, ds.map(location), LAYERS, 0.5)
    order = np.argsort(-np.asarray(probabilities, dtype=np.float64), kind="stable")
    entries = []
    for rank, m in reversed(list(enumerate(order))):  # the most probable drawn last, on top
        colour = LINE_CYCLE_RGB[rank % len(LINE_CYCLE_RGB)]
        _polyline(canvas, np.r_[present[None], modes[m]], colour, 4 if rank == 0 else 2)
        entries.append((labels[m] if labels is not None else f"mode {m}", colour))
    _polyline(canvas, np.r_[np.asarray(past_xy, np.float64).reshape(-1, 2), present[None]], PAST_RGB, 2)
    future = np.asarray(future_xy, np.float64).reshape(-1, 2)
    _polyline(canvas, np.r_[present[None], future], FUTURE_RGB, 2)
    canvas.dots(future, FUTURE_RGB, 3)
    canvas.dots(present[None], AGENT_RGB, 6)
    legend.draw_legend(canvas.image, [("past", PAST_RGB), ("ground truth", FUTURE_RGB), *entries[::-1]],
                       corner="top-right")
    if title:
        legend.draw_caption(canvas.image, title, corner="bottom-left")
    return np.ascontiguousarray(canvas.image[:, :, ::-1])


def _polyline(canvas: MapCanvas, xy: np.ndarray, rgb, thickness: int) -> None:
    xy = xy[np.isfinite(xy).all(axis=1)]
    if len(xy) >= 2:
        canvas.lines([shapely.linestrings(xy)], rgb, thickness)


def worst_agents(agents: pl.DataFrame, count: int) -> list[int]:
    """The `agent` numbers of the `count` agents with the largest final error of their most probable mode."""
    column = "MinFDEK_1" if "MinFDEK_1" in agents.columns else next(
        (c for c in agents.columns if c.endswith("_1") and agents[c].dtype == pl.Float64), None)
    ranked = agents.sort(column, descending=True, nulls_last=True, maintain_order=True) if column else agents
    return ranked["agent"].head(count).to_list()


def write_trajectory_plots(plot_dir: Path, ds, result, *, count: int = DEFAULT_COUNT) -> list[Path]:
    """`trajectory_picture` of the `worst_agents` of `result` (a `PredictionResult` of `ds`) as
    `plot_dir/<n>_<instance>_<sample>.png` (n: their order)."""
    from nuparquet.dataset import as_dataset
    from nuparquet.frames.annotation_chains import AnnotationChains

    ds = as_dataset(ds)
    submission, agents, futures, modes = result.submission, result.agents, result.futures, result.modes

    chosen = worst_agents(agents, count)
    if not chosen:
        return []
    plot_dir.mkdir(parents=True, exist_ok=True)
    chains, _ = AnnotationChains.of(ds)
    rows = chains.rows_at([submission.samples[a] for a in chosen], [submission.instances[a] for a in chosen])
    pasts = chains.windows(rows, HISTORY_S, "prev")
    has_map = "map" in {name.split("/")[0] for name in ds.datasets}
    written = []
    for n, (agent, row, past) in enumerate(zip(chosen, rows, pasts)):
        info = agents.row(agent, named=True)
        errors = modes.filter(pl.col("agent") == agent).sort("mode")
        labels = [f"p={p:.2f} ADE {a:.1f} FDE {f:.1f} m" for p, a, f in
                  zip(errors["probability"], errors["ade_m"], errors["fde_m"])]
        picture = trajectory_picture(
            ds, info["location"] if has_map and info["location"] else None, chains.translation[row][:2],
            chains.translation[past][:, :2][::-1], futures[agent], submission.prediction[agent],
            submission.probabilities[agent], labels=labels,
            title=f"{info['scene_name']}  instance {info['instance_token'][:8]}  sample {info['sample_token'][:8]}")
        path = plot_dir / f"{n:02d}_{info['instance_token']}_{info['sample_token']}.png"
        cv2.imwrite(str(path), picture[:, :, ::-1])
        written.append(path)
    return written
