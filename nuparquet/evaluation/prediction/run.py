"""The trajectory prediction evaluation job: the submission's records checked and placed on their annotations,
each agent's ground-truth future walked from the converted `tables/sample_annotation` (the devkit's
`PredictHelper.get_future_for_agent(..., in_agent_frame=False)`), the metrics of the configuration computed per
agent into the devkit's containers and aggregated, and its metrics dict written as `prediction_metrics.json` (with
`agents.parquet`, one row per agent, and `modes.parquet`, one row per agent and mode).

```python
from nuparquet.evaluation.prediction import evaluate_prediction
result = evaluate_prediction("OUT", "predictions.json", "eval/", split="val")
result.metrics["MinADEK"]["RowMean"], result.agents.sort("MinADEK_5")
```
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from nuparquet.errors import InputError
from nuparquet.evaluation.options import EvalOptions
from nuparquet.evaluation.prediction.config import PredictionConfig, resolve_prediction_config
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

RESULTS_NAME = "prediction_metrics.json"


@dataclass
class PredictionResult:
    """What a prediction evaluation found and wrote.

    metrics: `compute_metrics`'s dict ({metric name: {aggregator: [values]}}, also `summary`); agents: one row per
    submission record (its tokens, scene, location, steps, and each metric per agent under the devkit's flattened
    names: MinADEK_5, MissRateTopK_2_1, OffRoadRate...); modes: one row per (agent, mode) (probability, rank: 0 the
    most probable, ade_m, fde_m, max_distance_m, off_road); out: the directory written (None: nothing written);
    notes: what a user should know; slices: with `by`, one row per (by, slice): its agents and each metric's RowMean
    over them under the flattened names (None without `by`); submission, futures: the records read and each
    agent's ground-truth future (global x, y), for pictures."""

    metrics: dict
    agents: pl.DataFrame
    modes: pl.DataFrame
    out: Path | None = None
    notes: list[str] = field(default_factory=list)
    slices: pl.DataFrame | None = None
    submission: object = field(default=None, repr=False)
    futures: list = field(default_factory=list, repr=False)

    @property
    def summary(self) -> dict:
        return self.metrics


def evaluate_prediction(dataset, results, out=None, options: EvalOptions | None = None, *,
                        on_progress: OnProgress | None = None, **fields) -> PredictionResult:
    """Evaluate a trajectory prediction submission on a converted dataset exactly as nuscenes-devkit's
    `compute_metrics` (with its `PredictHelper`) does: MinADEK, MinFDEK, MissRateTopK and OffRoadRate.

    `dataset`: a `Dataset` or the path of a converted output with the map expansion; `results`: the submission (a
    JSON list of `Prediction` records); `out`: the directory to write (None: nothing written). Settings as an
    `EvalOptions` (its task prediction) or as its keywords (`split=`, `config=`, `config_file=`, `overwrite=`).

    Raises:
        UsageError: bad settings (unknown split or configuration, an `out` that holds files).
        InputError: a submission the devkit would refuse or mis-evaluate (the message names the record and the
            field), a record of a sample outside the split, or an agent whose future the devkit cannot compare.
    """
    from nuparquet.dataset import as_dataset
    from nuparquet.errors import UsageError
    from nuparquet.evaluation.prediction.submission import read_submission
    from nuparquet.evaluation.run import _check_out

    options = resolve(EvalOptions, options, {"task": "prediction", **fields})
    config = resolve_prediction_config(options.config, options.config_file)
    ds = as_dataset(dataset)
    out = Path(out) if out is not None else None
    if out is not None:
        _check_out(out, ds, options.overwrite)
    by = tuple(dict.fromkeys(options.by))
    if not by and options.bins:
        raise UsageError("--bins needs --by")
    with Reporter(on_progress, "eval prediction", total=4, unit="step") as rep:
        rep.note("read the submission")
        submission = read_submission(results)
        rep.advance()
        agents, futures = ground_truth(ds, submission, config, options.split)
        rep.advance()
        metrics, agents, modes = score(ds, submission, futures, agents, config)
        rep.advance()
        slices = agent_slices(ds, agents, by, options.bins) if by else None
        result = PredictionResult(metrics=metrics, agents=agents, modes=modes, out=out, slices=slices,
                                  submission=submission, futures=futures)
        if out is not None:
            write(out, result)
        rep.advance()
    return result


def ground_truth(ds, submission, config: PredictionConfig, split: str) -> tuple[pl.DataFrame, list[np.ndarray]]:
    """One row per record (agent, instance_token, sample_token, scene_name, location) and each agent's (L, 2)
    future x, y (global metres, nearest first, over `config.seconds`); InputError for a record the devkit cannot
    evaluate."""
    from nuparquet.evaluation.prediction.submission import where
    from nuparquet.evaluation.splits import split_scene_names
    from nuparquet.frames.annotation_chains import AnnotationChains

    chains, _ = AnnotationChains.of(ds)
    samples = (ds.scan("tables/sample").select("token", "scene_token").collect()
               .join(ds.scan("tables/scene").select(pl.col("token").alias("scene_token"), pl.col("name"),
                                                    "log_token").collect(), on="scene_token", how="left")
               .join(ds.scan("tables/log").select(pl.col("token").alias("log_token"), "location").collect(),
                     on="log_token", how="left"))
    agents = (pl.DataFrame({"agent": np.arange(len(submission), dtype=np.int64),
                            "instance_token": submission.instances, "sample_token": submission.samples},
                           schema={"agent": pl.Int64, "instance_token": pl.String, "sample_token": pl.String})
              .join(samples.select(pl.col("token").alias("sample_token"), pl.col("name").alias("scene_name"),
                                   "location"), on="sample_token", how="left", maintain_order="left"))
    rows = chains.rows_at(submission.samples, submission.instances)
    known_sample = set(samples["token"].to_list())
    in_split = set(split_scene_names(split, dataroot=ds.dataroot, version=ds.version))
    scene_names = agents["scene_name"].to_list()

    def record(i: int) -> str:
        return where(i, {"instance": submission.instances[i], "sample": submission.samples[i]})

    for i in np.flatnonzero(rows < 0):
        what = ("no such sample" if submission.samples[i] not in known_sample
                else "the instance has no annotation at that sample")
        raise InputError(f"{record(i)}: {what}")
    for i, name in enumerate(scene_names):
        if name not in in_split:
            raise InputError(f"{record(i)}: its sample is in scene {name}, not a scene of split {split}")
    windows = chains.windows(rows, config.seconds, "next")
    futures = [chains.translation[w][:, :2] for w in windows]
    for i, (future, prediction) in enumerate(zip(futures, submission.prediction)):
        steps, length = prediction.shape[1], len(future)
        if length == 0 or (steps != length and 1 not in (steps, length)):
            raise InputError(f"{record(i)}: prediction has {steps} steps and the agent's ground-truth future over "
                             f"{config.seconds} s has {length} (the devkit compares them step by step: they must be "
                             "equal)")
    return agents, futures


def score(ds, submission, futures: list[np.ndarray], agents: pl.DataFrame, config: PredictionConfig
          ) -> tuple[dict, pl.DataFrame, pl.DataFrame]:
    """The devkit's metrics dict, and the agents and modes tables (see PredictionResult)."""
    from nuparquet.evaluation.prediction.metrics import mode_errors, ranked_order, top_k
    from nuparquet.evaluation.prediction.offroad import drivable_area, off_road_modes

    n = len(submission)
    errors = mode_errors(submission.prediction, futures)
    orders = [ranked_order(p) for p in submission.probabilities]
    off_road = None
    if any(m.kind == "OffRoadRate" for m in config.metrics):
        locations = agents["location"].to_list()
        masks = {location: drivable_area(ds, location) for location in dict.fromkeys(locations)}
        off_road = off_road_modes(submission.prediction, [masks[location] for location in locations])
    containers, columns = {}, {}
    for metric in config.metrics:
        if metric.kind == "OffRoadRate":
            container = np.array([[flags.sum() / len(flags)] for flags in off_road], dtype=np.float64).reshape(n, 1)
            columns[metric.name] = container[:, 0]
        else:
            per_mode = {"MinADEK": errors.ade_m, "MinFDEK": errors.fde_m}.get(metric.kind)
            if per_mode is None:  # MissRateTopK: a mode misses when its largest displacement reaches the tolerance
                per_mode = [largest >= metric.tolerance for largest in errors.max_m]
            container = np.zeros((n, len(metric.k_to_report)))
            for i in range(n):
                container[i] = top_k(per_mode[i], orders[i], metric.k_to_report)
            for j, k in enumerate(metric.k_to_report):
                columns[f"{metric.name}_{k}"] = container[:, j]
        containers[metric.name] = container
    with np.errstate(invalid="ignore", divide="ignore"):  # no record: the devkit's mean of nothing, NaN
        metrics = {m.name: {agg: containers[m.name].mean(axis=0).tolist() for agg in m.aggregators}
                   for m in config.metrics}
    modes_per_agent = np.array([len(p) for p in submission.prediction], dtype=np.int64)
    agent_table = agents.with_columns(
        modes=pl.Series(modes_per_agent, dtype=pl.Int64),
        predicted_steps=pl.Series([p.shape[1] for p in submission.prediction], dtype=pl.Int64),
        future_steps=pl.Series([len(f) for f in futures], dtype=pl.Int64),
        **{name: pl.Series(values, dtype=pl.Float64) for name, values in columns.items()})
    rank = [np.argsort(order) for order in orders]
    concat = (lambda arrays, dtype: np.concatenate(arrays).astype(dtype) if n else np.zeros(0, dtype))
    mode_table = pl.DataFrame({
        "agent": np.repeat(np.arange(n, dtype=np.int64), modes_per_agent),
        "mode": concat([np.arange(m) for m in modes_per_agent], np.int64),
        "probability": concat(submission.probabilities, np.float64),
        "rank": concat(rank, np.int64),
        "ade_m": concat(errors.ade_m, np.float64),
        "fde_m": concat(errors.fde_m, np.float64),
        "max_distance_m": concat(errors.max_m, np.float64),
        **({"off_road": concat(off_road, bool)} if off_road is not None else {}),
    })
    return metrics, agent_table, mode_table


def write(out: Path, result: PredictionResult) -> None:
    """`prediction_metrics.json` (the devkit's dict as its `main` dumps it: indent 2, key order kept, NaN written
    as NaN), `agents.parquet` and `modes.parquet`, into `out` at once (`atomic_directory`). The pictures of
    `plots/trajectories/` are the rendering layer's (`rendering.pictures.trajectories`, drawn by `nuparquet eval`)."""
    from nuparquet.atomic import atomic_directory

    with atomic_directory(out, overwrite=True, checked=True) as partial:
        (partial / RESULTS_NAME).write_text(json.dumps(result.metrics, indent=2))
        result.agents.write_parquet(partial / "agents.parquet")
        result.modes.write_parquet(partial / "modes.parquet")
        if result.slices is not None:
            result.slices.write_parquet(partial / "slices.parquet")


def agent_slices(ds, agents: pl.DataFrame, by: tuple[str, ...], bins) -> pl.DataFrame:
    """The metrics per slice of the agents (`evaluation.slices`: an agent is the ground-truth annotation it is
    predicted from, placed by its own value; there is no prediction to place): the RowMean of each per-agent
    figure over the slice's agents, as the devkit's mean over the records of a submission holding only those."""
    from nuparquet.evaluation.slices import dimension, needed_columns, parse_bins

    bins = parse_bins(bins) if bins else None
    annotation_names = ds.scan("annotations").collect_schema().names()
    scene_names = ds.scan("scenes").collect_schema().names()
    annotation_columns, scene_columns = needed_columns(by, annotation_names, scene_names)
    wanted = list(dict.fromkeys(["sample_token", "instance_token", "scene_token", "scene_name", "timestamp",
                                 "attribute_names", "distance_to_ego_m", *annotation_columns]))
    rows = (agents.select("sample_token", "instance_token")
            .join(ds.scan("annotations").select(wanted).collect().unique(["sample_token", "instance_token"],
                                                                         keep="last"),
                  on=["sample_token", "instance_token"], how="left", maintain_order="left"))
    scenes = ds.scan("scenes").select(list(dict.fromkeys(["token", "name", "description", "log_location",
                                                          *scene_columns]))).collect()
    per_agent = rows.select("sample_token", "scene_token", "scene_name", "timestamp").join(
        scenes, left_on="scene_token", right_on="token", how="left", maintain_order="left")
    attribute = np.array([names[0] if names else "" for names in rows["attribute_names"].to_list()], dtype=object)
    n = agents.height
    # per metric its (n, k) C-ordered container, as the devkit's: numpy's mean over axis 0 sums an (n, 1) column
    # pairwise and the rows of a wider one in order, so the shape decides the last bit
    metrics = {}
    for column in agents.columns:
        for prefix in ("MinADEK", "MinFDEK", "MissRateTopK", "OffRoadRate"):
            if column.startswith(prefix):
                key = column if prefix == "OffRoadRate" else column.rsplit("_", 1)[0]
                metrics.setdefault(key, []).append(column)
    containers = {key: np.ascontiguousarray(agents.select(columns).to_numpy().reshape(n, len(columns)))
                  for key, columns in metrics.items()}
    out = []
    for name in by:
        dim = dimension(name, gt_ego_distance_m=rows["distance_to_ego_m"].cast(pl.Float64).fill_null(np.nan).to_numpy(),
                        pred_ego_distance_m=np.zeros(0), gt_annotations=rows, gt_attribute=attribute,
                        pred_attribute=np.zeros(0, dtype=object), gt_sample=np.arange(n), pred_sample=np.zeros(0, int),
                        sample_scene=per_agent, pred_matched_gt=np.zeros(0, int), bins=bins)
        for label in dim.labels:
            members = dim.gt_label == label
            row = {"by": name, "slice": label, "agents": int(members.sum())}
            for key, columns in metrics.items():
                row |= dict(zip(columns, containers[key][members].mean(axis=0).tolist()))
            out.append(row)
    figures = [c for columns in metrics.values() for c in columns]
    return pl.DataFrame(out, schema={"by": pl.String, "slice": pl.String, "agents": pl.Int64,
                                     **{f: pl.Float64 for f in figures}})
