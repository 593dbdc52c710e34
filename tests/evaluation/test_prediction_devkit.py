"""The prediction evaluation against nuscenes-devkit's `compute_metrics` itself (its `NuScenes`, `PredictHelper` and
`predict_2020_icra` config with OffRoadRate's drivable-area masks) on a generated map set with 7 s scenes (agents
with full and shorter futures): seeded perturbed submissions reaching the edges (short futures predicted to their
length, single-step predictions, a single mode, up to 25 modes, k larger than the number of modes, tied
probabilities as floats and as integers, paths far off the map, paths on the drivable area's edge pixel and just
beside it). The metrics dicts are compared as JSON text (keys, order, every float exactly: the same numpy
operations per element, the same scipy spline, the same mask pixels); the per-agent figures against the devkit's
metric objects called on each record.

The devkit's `load_all_maps` opens the four nuScenes maps; the generated set has two of its locations, so its
module list is cut to those (the masks it builds are its own)."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from tests.conftest import SYNTH_VERSION, converted, generated_root

pytestmark = pytest.mark.devkit

SPLIT = "train"  # scene-0003 of the six is in val: the records are of the others


@pytest.fixture(scope="module")
def pred_root(tmp_path_factory):
    from nuparquet.synth import synthesize

    return generated_root(tmp_path_factory, "prediction-synth", lambda root: synthesize(
        root, scenes=6, samples_per_scene=14, seed=5, version=SYNTH_VERSION, with_can_bus=False))


@pytest.fixture(scope="module")
def pred_out(pred_root, tmp_path_factory):
    return converted(tmp_path_factory, "prediction-out", pred_root, SYNTH_VERSION)


@pytest.fixture(scope="module")
def devkit(pred_root):
    """(NuScenes, PredictHelper, predict_2020_icra config) of the devkit, its map list cut to the set's maps."""
    from nuscenes import NuScenes
    from nuscenes.eval.prediction.config import load_prediction_config
    from nuscenes.prediction import PredictHelper
    from nuscenes.prediction.input_representation import static_layers

    nusc = NuScenes(SYNTH_VERSION, dataroot=str(pred_root), verbose=False)
    helper = PredictHelper(nusc)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(static_layers, "locations", sorted(p.stem for p in (pred_root / "maps" / "expansion").glob("*")))
        config = load_prediction_config(helper)
    return nusc, helper, config


@functools.cache
def agents(nusc, helper):
    """Every (instance, sample, future) of the split's scenes with at least one future step, in file order."""
    from nuscenes.utils.splits import create_splits_scenes

    scenes = {s["token"] for s in nusc.scene if s["name"] in create_splits_scenes()[SPLIT]}
    out = []
    for sample in nusc.sample:
        if sample["scene_token"] not in scenes:
            continue
        for token in sample["anns"]:
            ann = nusc.get("sample_annotation", token)
            future = helper.get_future_for_agent(ann["instance_token"], sample["token"], 6, in_agent_frame=False)
            if len(future):
                out.append((ann["instance_token"], sample["token"], future))
    return out


@functools.cache
def edge_pixel(devkit, location: str) -> tuple[int, int]:
    """(row, col) of a drivable pixel of the devkit's mask of `location` whose left neighbour is not drivable."""
    mask = devkit[2].metrics[-1].drivable_area_polygons[location]
    rows = np.flatnonzero(mask.any(axis=1))
    row = int(rows[len(rows) // 2])
    cols = np.flatnonzero((mask[row, 1:] != 0) & (mask[row, :-1] == 0)) + 1
    return row, int(cols[0])


def perturbed(devkit, seed: int, count: int = 100) -> list[dict]:
    """`count` records of the set's agents: the future plus noise (0.2 m to 30 m), 1 to 25 modes, ties, integer
    probabilities, single-step predictions, and modes standing on the drivable area's edge."""
    nusc, helper, config = devkit
    rng = np.random.default_rng(seed)
    chosen = agents(nusc, helper)
    chosen = [chosen[i] for i in np.sort(rng.choice(len(chosen), min(count, len(chosen)), replace=False))]
    records = []
    for i, (instance, sample, future) in enumerate(chosen):
        modes = int(rng.choice([1, 2, 3, 5, 12, 25], p=[0.2, 0.2, 0.2, 0.2, 0.15, 0.05]))
        steps = 1 if i % 17 == 0 else len(future)
        base = future[-1:] if steps == 1 else future
        prediction = base[None] + rng.normal(0, rng.choice([0.2, 1.0, 3.0, 30.0]), (modes, steps, 2))
        if i % 11 == 0:  # a mode standing still on the drivable area's edge pixel, another just left of it
            row, col = edge_pixel(devkit, helper.get_map_name_from_sample_token(sample))
            prediction[0] = [col / 10, row / 10 + 0.05]
            if modes > 1:
                prediction[1] = [np.nextafter(col / 10, 0), row / 10 + 0.05]
        if i % 13 == 0:
            prediction[-1] = [-1e4, 5.0]  # off the canvas
        kind = i % 4
        if kind == 0:
            probabilities = rng.random(modes).tolist()
        elif kind == 1:
            probabilities = rng.choice([0.1, 0.25], modes).tolist()  # ties
        elif kind == 2:
            probabilities = [int(v) for v in rng.integers(0, 3, modes)]  # integer ties: an int64 argsort
        else:
            probabilities = [1.0 / modes] * modes  # all equal
        records.append({"instance": instance, "sample": sample, "prediction": prediction.tolist(),
                        "probabilities": probabilities})
    return records


def write(tmp_path, records, name="predictions.json"):
    path = tmp_path / name
    path.write_text(json.dumps(records))
    return path


@pytest.mark.parametrize("seed", [1, 2])
def test_perturbed_submissions_equal_the_devkit(pred_out, devkit, seed, tmp_path):
    from nuscenes.eval.prediction.compute_metrics import compute_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    records = perturbed(devkit, seed)
    theirs = compute_metrics(records, devkit[1], devkit[2])
    ours = evaluate_prediction(pred_out, write(tmp_path, records), tmp_path / "eval", split=SPLIT)
    assert json.dumps(ours.metrics) == json.dumps(theirs)
    assert (tmp_path / "eval" / "prediction_metrics.json").read_text() == json.dumps(theirs, indent=2)
    # the edges were reached: short futures, single steps, off-road and on-road modes, k beyond the modes
    assert (ours.agents["future_steps"] < 12).any() and (ours.agents["future_steps"] == 12).any()
    assert (ours.agents["predicted_steps"] == 1).any() and (ours.agents["modes"] == 1).any()
    assert ours.modes["off_road"].any() and not ours.modes["off_road"].all()


def test_each_agent_and_mode_equals_the_devkit_metrics(pred_out, devkit, tmp_path):
    from nuscenes.eval.prediction.data_classes import Prediction
    from nuscenes.eval.prediction import metrics as their_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    records = perturbed(devkit, 3, count=120)
    ours = evaluate_prediction(pred_out, write(tmp_path, records), split=SPLIT)
    helper, config = devkit[1], devkit[2]
    for i, record in enumerate(records):
        prediction = Prediction.deserialize(record)
        truth = helper.get_future_for_agent(record["instance"], record["sample"], 6, in_agent_frame=False)
        row = ours.agents.row(i, named=True)
        assert row["future_steps"] == len(truth)
        for metric in config.metrics:
            values = np.asarray(metric(truth, prediction)).reshape(-1)
            names = [f"{metric.name}_{k}" for k in metric.k_to_report] if hasattr(metric, "k_to_report") else [
                metric.name]
            assert [row[n] for n in names] == values.tolist(), (i, metric.name)
        modes = ours.modes.filter(ours.modes["agent"] == i)
        stacked = their_metrics.stack_ground_truth(truth, prediction.number_of_modes)
        assert modes["ade_m"].to_list() == their_metrics.mean_distances(prediction.prediction, stacked)[0].tolist()
        assert modes["fde_m"].to_list() == their_metrics.final_distances(prediction.prediction, stacked)[0].tolist()
        order = np.flip(prediction.probabilities.argsort(axis=-1), axis=-1)
        assert modes["rank"].to_numpy()[order].tolist() == list(range(len(order)))
        # a mode is its place in the record's prediction, with the probability given there
        assert modes["mode"].to_list() == list(range(prediction.number_of_modes))
        assert modes["probability"].to_list() == prediction.probabilities.tolist()
        assert row["predicted_steps"] == prediction.prediction.shape[1] and row["modes"] == prediction.number_of_modes


def test_tied_probabilities_rank_as_the_devkits_argsort(pred_out, devkit, tmp_path):
    """All modes equally probable, each a different distance off: the top 1 is the mode the devkit's unstable
    argsort puts last, for float and for integer probabilities (and 25 modes: past insertion sort's 16)."""
    from nuscenes.eval.prediction.compute_metrics import compute_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    instance, sample, future = next(a for a in agents(devkit[0], devkit[1]) if len(a[2]) == 12)
    records = []
    for modes, probability in ((3, 0.5), (25, 0.04), (25, 1), (20, 0)):
        prediction = future[None] + (np.arange(modes) + 1.0)[:, None, None]
        records.append({"instance": instance, "sample": sample, "prediction": prediction.tolist(),
                        "probabilities": [probability] * modes})
    ours = evaluate_prediction(pred_out, write(tmp_path, records), split=SPLIT)
    for i, record in enumerate(records):
        theirs = compute_metrics([record], devkit[1], devkit[2])
        expected_top = np.flip(np.array(record["probabilities"]).argsort())[0]
        assert ours.agents["MinADEK_1"][i] == theirs["MinADEK"]["RowMean"][0]
        assert ours.modes.filter(ours.modes["agent"] == i)["rank"][int(expected_top)] == 0


def test_a_configuration_file_keeps_the_devkits_names_and_k_beyond_the_modes(pred_out, devkit, tmp_path):
    from nuscenes.eval.prediction.compute_metrics import compute_metrics
    from nuscenes.eval.prediction.config import PredictionConfig

    from nuparquet.evaluation.prediction import evaluate_prediction

    content = {"seconds": 3, "metrics": [
        {"k_to_report": [1, 30], "name": "MissRateTopK", "aggregators": [{"name": "RowMean"}], "tolerance": 2.0},
        {"k_to_report": [2, 1], "name": "MinADEK", "aggregators": [{"name": "RowMean"}]}]}
    nusc, helper = devkit[0], devkit[1]
    records = []
    for instance, sample, _ in agents(nusc, helper)[:60]:
        future = helper.get_future_for_agent(instance, sample, 3, in_agent_frame=False)
        records.append({"instance": instance, "sample": sample, "prediction": (future[None] + 1.5).tolist(),
                        "probabilities": [1.0]})
    # a second miss rate whose tolerance is exactly one mode's largest displacement: a miss there (>=)
    from nuscenes.eval.prediction import metrics as their_metrics

    truth = helper.get_future_for_agent(records[0]["instance"], records[0]["sample"], 3, in_agent_frame=False)
    exact = float(their_metrics.max_distances(np.array(records[0]["prediction"]),
                                              their_metrics.stack_ground_truth(truth, 1))[0, 0])
    content["metrics"].append({"k_to_report": [1], "name": "MissRateTopK", "aggregators": [{"name": "RowMean"}],
                               "tolerance": exact})
    path = tmp_path / "config.json"
    path.write_text(json.dumps(content))
    theirs = compute_metrics(records, helper, PredictionConfig.deserialize(content, helper))
    ours = evaluate_prediction(pred_out, write(tmp_path, records), config_file=path, split=SPLIT)
    assert json.dumps(ours.metrics) == json.dumps(theirs)
    assert list(ours.metrics) == ["MissRateTopK_2.0", "MinADEK", f"MissRateTopK_{exact}"]
    assert ours.agents[f"MissRateTopK_{exact}_1"][0] == 1.0


def test_the_cli_writes_the_devkits_dict_and_the_tables(pred_out, devkit, tmp_path, capsys):
    from nuscenes.eval.prediction.compute_metrics import compute_metrics
    import polars as pl

    from nuparquet.cli.main import main

    records = perturbed(devkit, 4, count=40)
    path = write(tmp_path, records)
    code = main(["eval", str(pred_out), "--task", "prediction", "--results", str(path), "--split", SPLIT,
                 "--out", str(tmp_path / "eval"), "--quiet"])
    assert code == 0
    theirs = compute_metrics(records, devkit[1], devkit[2])
    assert json.loads((tmp_path / "eval" / "prediction_metrics.json").read_text()) == theirs
    assert "OffRoadRate (RowMean)" in capsys.readouterr().out
    agents_table = pl.read_parquet(tmp_path / "eval" / "agents.parquet")
    assert agents_table["instance_token"].to_list() == [r["instance"] for r in records]
    assert pl.read_parquet(tmp_path / "eval" / "modes.parquet").height == sum(len(r["probabilities"]) for r in records)


def test_an_empty_submission_gives_the_devkits_nan(pred_out, devkit, tmp_path):
    from nuscenes.eval.prediction.compute_metrics import compute_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    with np.errstate(invalid="ignore", divide="ignore"), pytest.warns(RuntimeWarning):
        theirs = compute_metrics([], devkit[1], devkit[2])
    ours = evaluate_prediction(pred_out, write(tmp_path, []), split=SPLIT)
    assert json.dumps(ours.metrics) == json.dumps(theirs)


def _record(devkit, **changes):
    instance, sample, future = next(a for a in agents(devkit[0], devkit[1]) if len(a[2]) == 12)
    record = {"instance": instance, "sample": sample, "prediction": [future.tolist()], "probabilities": [1.0]}
    return {**record, **changes}


@pytest.mark.parametrize("change, message", [
    ({"sample": "nope"}, r"record 1 \(instance .*, sample 'nope'\): no such sample"),
    ({"instance": "nope"}, r"record 1 \(instance 'nope', .*\): the instance has no annotation at that sample"),
    ({"prediction": [[0.0, 0.0]]}, r"record 1 .*prediction must be modes x steps x 2 .*\(1, 2\)"),
    ({"prediction": [[[0.0, 0.0, 0.0]]]}, r"record 1 .*prediction must be modes x steps x 2"),
    ({"prediction": [[[0.0, float("nan")]]]}, r"record 1 .*prediction\[0, 0, 1\] is nan"),
    ({"probabilities": [0.5, 0.5]}, r"record 1 .*probabilities must hold one number per mode \(1\)"),
    ({"probabilities": [None]}, r"record 1 .*probabilities must hold numbers only"),
    ({"prediction": [[[1.0, 2.0]] * 3]}, r"record 1 .*prediction has 3 steps and the agent's ground-truth future"),
    ({"prediction": [[[1.0, 2.0]]] * 26, "probabilities": [0.1] * 26}, "26 modes, more than the devkit's 25"),
])
def test_malformed_records_are_refused_naming_the_record_and_field(pred_out, devkit, tmp_path, change, message):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.prediction import evaluate_prediction

    records = [_record(devkit), _record(devkit, **change)]
    if "steps" in message:  # the devkit cannot compare them either: its broadcast fails
        from nuscenes.eval.prediction.compute_metrics import compute_metrics

        if len(records[1]["prediction"][0]) not in (1, len(records[0]["prediction"][0])):
            with pytest.raises(ValueError):
                compute_metrics(records[1:], devkit[1], devkit[2])
    with pytest.raises(InputError, match=message):
        evaluate_prediction(pred_out, write(tmp_path, records), split=SPLIT)


def test_an_agent_without_future_and_a_sample_outside_the_split_are_refused(pred_out, devkit, tmp_path):
    from nuparquet.errors import InputError
    from nuparquet.evaluation.prediction import evaluate_prediction

    nusc = devkit[0]
    last = next(a for a in nusc.sample_annotation if not a["next"])
    record = {"instance": last["instance_token"], "sample": last["sample_token"], "prediction": [[[0.0, 0.0]]],
              "probabilities": [1.0]}
    with pytest.raises(InputError, match="record 0 .* has 0"):
        evaluate_prediction(pred_out, write(tmp_path, [record]), split=SPLIT)
    val_scene = next(s for s in nusc.scene if s["name"] == "scene-0003")
    outside = _record(devkit)
    outside["sample"] = val_scene["first_sample_token"]
    outside["instance"] = nusc.get("sample_annotation", nusc.get("sample", outside["sample"])["anns"][0])[
        "instance_token"]
    with pytest.raises(InputError, match="record 1 .*scene scene-0003, not a scene of split train"):
        evaluate_prediction(pred_out, write(tmp_path, [_record(devkit), outside]), split=SPLIT)


def test_modes_on_and_beside_the_drivable_areas_edge_pixel(pred_out, devkit, tmp_path):
    """Standing modes (one distinct point: no spline) at the left edge x of a drivable pixel, half a pixel inside,
    half a pixel outside, one ulp short of the edge, and half a pixel below zero (truncated to pixel 0, on the
    canvas): each flag is the devkit's OffRoadRate of that mode alone."""
    from nuscenes.eval.prediction.data_classes import Prediction

    from nuparquet.evaluation.prediction import evaluate_prediction

    nusc, helper, config = devkit
    instance, sample, future = next(a for a in agents(nusc, helper) if len(a[2]) == 12)
    row, col = edge_pixel(devkit, helper.get_map_name_from_sample_token(sample))
    y = (row + 0.5) / 10
    xs = [col / 10, (col + 0.5) / 10, (col - 0.5) / 10, np.nextafter(col / 10, 0), -0.05]
    prediction = np.array([[[x, y]] * 12 for x in xs])
    record = {"instance": instance, "sample": sample, "prediction": prediction.tolist(),
              "probabilities": [0.2] * len(xs)}
    ours = evaluate_prediction(pred_out, write(tmp_path, [record]), split=SPLIT)
    off_road = config.metrics[-1]
    theirs = [bool(off_road(future, Prediction(instance, sample, prediction[i:i + 1], np.ones(1)))[0])
              for i in range(len(xs))]
    assert ours.modes["off_road"].to_list() == theirs
    assert theirs[1:3] == [False, True]


def test_a_slice_is_the_devkits_metrics_of_the_records_it_holds(pred_out, devkit, tmp_path):
    """--by scene and --by distance: each slice's figures equal compute_metrics run on the submission's records of
    that slice alone (the same rows, in the same order, averaged)."""
    from nuscenes.eval.prediction.compute_metrics import compute_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    records = perturbed(devkit, 5, count=60)
    ours = evaluate_prediction(pred_out, write(tmp_path, records), tmp_path / "eval", split=SPLIT,
                               by=("scene", "distance"), bins=("0", "15", "30"))
    assert ours.slices["by"].unique().sort().to_list() == ["distance", "scene"]
    assert (tmp_path / "eval" / "slices.parquet").is_file()
    nusc = devkit[0]
    for by in ("scene", "distance"):
        table = ours.slices.filter(ours.slices["by"] == by)
        assert table["agents"].sum() == len(records)
        for row in table.iter_rows(named=True):
            if by == "scene":
                members = [r for r in records
                           if nusc.get("scene", nusc.get("sample", r["sample"])["scene_token"])["name"] == row["slice"]]
            else:
                low, high = {"0-15m": (0, 15), "15-30m": (15, 30), "30m+": (30, np.inf)}[row["slice"]]
                distance = ours.agents.join(
                    __import__("nuparquet").open(pred_out).scan("annotations").select(
                        "sample_token", "instance_token", "distance_to_ego_m").collect(),
                    on=["sample_token", "instance_token"], how="left", maintain_order="left")["distance_to_ego_m"]
                members = [r for r, d in zip(records, distance.to_list()) if low <= d < high]
            theirs = compute_metrics(members, devkit[1], devkit[2])
            assert row["agents"] == len(members)
            assert row["MinADEK_5"] == theirs["MinADEK"]["RowMean"][1]
            assert row["MissRateTopK_2_10"] == theirs["MissRateTopK_2"]["RowMean"][2]
            assert row["OffRoadRate"] == theirs["OffRoadRate"]["RowMean"][0]


def test_the_drivable_area_is_the_devkits_mask_at_every_pixel_of_sampled_rows(pred_out, devkit):
    """Every pixel of 300 rows through each map's drivable area (its edges included: OpenCV's outlines are where a
    painting of a part of the canvas would differ) against the devkit's OffRoadRate mask."""
    import nuparquet
    from nuparquet.evaluation.prediction.offroad import drivable_area

    ds = nuparquet.open(pred_out)
    for location, theirs in devkit[2].metrics[-1].drivable_area_polygons.items():
        area = drivable_area(ds, location)
        assert area.canvas_size == theirs.shape
        rows = np.flatnonzero(theirs.any(axis=1))
        rows = rows[np.linspace(0, len(rows) - 1, 300).astype(int)]
        grid_rows, grid_cols = np.repeat(rows, theirs.shape[1]), np.tile(np.arange(theirs.shape[1]), len(rows))
        assert np.array_equal(area.at(grid_rows, grid_cols), theirs[grid_rows, grid_cols]), location


def test_the_named_configuration_serializes_as_the_devkits(devkit):
    from nuparquet.evaluation.config import named_config
    from nuparquet.evaluation.prediction.config import PredictionConfig

    ours = named_config("predict_2020_icra", PredictionConfig)
    assert json.dumps(ours.serialize()) == json.dumps(devkit[2].serialize())
    assert PredictionConfig.from_dict(ours.serialize()) == ours


_ROW = {"name": "RowMean"}


@pytest.mark.parametrize("content, message", [
    ([], "an object with \"metrics\" and \"seconds\""),
    ({"metrics": [], "seconds": 6}, "metrics must be a non-empty list"),
    ({"metrics": [{"name": "OffRoadRate", "aggregators": [_ROW]}], "seconds": 0}, "seconds must be a positive"),
    ({"metrics": [{"name": "MinADE", "aggregators": [_ROW]}], "seconds": 6}, r"metrics\[0\]: name must be one of"),
    ({"metrics": [{"name": "OffRoadRate", "aggregators": [{"name": "Max"}]}], "seconds": 6},
     r"metrics\[0\] \(OffRoadRate\): aggregators"),
    ({"metrics": [{"name": "MinFDEK", "aggregators": [_ROW], "k_to_report": [1, 0]}], "seconds": 6},
     r"metrics\[0\] \(MinFDEK\): k_to_report must be a list of positive integers"),
    ({"metrics": [{"name": "MinFDEK", "aggregators": [_ROW], "k_to_report": [1.0]}], "seconds": 6}, "k_to_report"),
    ({"metrics": [{"name": "MissRateTopK", "aggregators": [_ROW], "k_to_report": [1]}], "seconds": 6},
     r"\(MissRateTopK\): tolerance must be a number"),
    ({"metrics": [{"name": "OffRoadRate", "aggregators": [_ROW]}] * 2, "seconds": 6}, "metric names repeat"),
])
def test_a_configuration_the_devkit_would_refuse_or_misread_is_refused(content, message):
    from nuparquet.errors import UsageError
    from nuparquet.evaluation.prediction.config import PredictionConfig

    with pytest.raises(UsageError, match=message):
        PredictionConfig.from_dict(content, where="my.json")


def test_predicted_trajectories_are_drawn_over_the_map_by_rank():
    from nuparquet.rendering.pictures.trajectories import FUTURE_RGB, trajectory_picture
    from nuparquet.rendering.palette import LINE_CYCLE_RGB

    future = np.c_[np.arange(1.0, 11.0), np.zeros(10)]
    modes = np.stack([np.c_[np.arange(1.0, 11.0), np.full(10, 5.0)],    # probability 0.2: ranked second
                      np.c_[np.arange(1.0, 11.0), np.full(10, -5.0)]])  # 0.8: first
    picture = trajectory_picture(None, None, (0.0, 0.0), np.zeros((0, 2)), future, modes, [0.2, 0.8])
    # drawn extent (-10, -15) to (20, 15) m on 700 px: pixel (u, v) of (x, y) = ((x + 10), (15 - y)) * 700 / 30 - 0.5
    s = 700 / 30

    def at(x, y):
        return tuple(int(c) for c in picture[round((15 - y) * s - 0.5), round((x + 10) * s - 0.5)])

    assert picture.shape == (700, 700, 3)
    assert at(5.5, -5.0) == LINE_CYCLE_RGB[0] and at(5.5, 5.0) == LINE_CYCLE_RGB[1]
    assert at(5.5, 0.0) == FUTURE_RGB and at(5.5, 2.5) == (255, 255, 255)


def test_the_eval_folder_holds_the_worst_agents_trajectories(pred_out, devkit, tmp_path):
    import cv2

    from nuparquet.cli.main import main
    from nuparquet.evaluation.prediction import evaluate_prediction

    records = perturbed(devkit, 3, count=20)
    assert main(["eval", str(pred_out), "--task", "prediction", "--results", str(write(tmp_path, records)),
                 "--split", SPLIT, "--out", str(tmp_path / "eval"), "--quiet"]) == 0
    ours = evaluate_prediction(pred_out, write(tmp_path, records), split=SPLIT)
    pictures = sorted((tmp_path / "eval" / "plots" / "trajectories").glob("*.png"))
    assert len(pictures) == 8
    worst = ours.agents.sort("MinFDEK_1", descending=True).row(0, named=True)
    assert pictures[0].name == f"00_{worst['instance_token']}_{worst['sample_token']}.png"
    image = cv2.imread(str(pictures[0]))
    assert image.shape[:2] == (700, 700) and len(np.unique(image.reshape(-1, 3), axis=0)) > 10  # map, lines, text
    assert main(["eval", str(pred_out), "--task", "prediction", "--results", str(write(tmp_path, records)),
                 "--split", SPLIT, "--out", str(tmp_path / "bare"), "--no-plots", "--quiet"]) == 0
    assert not (tmp_path / "bare" / "plots").exists()


def test_a_configuration_object_is_taken_as_given_and_a_metric_entry_that_is_no_object_is_refused():
    from nuparquet.errors import UsageError
    from nuparquet.evaluation.prediction.config import PredictionConfig, resolve_prediction_config

    custom = PredictionConfig.from_dict({"seconds": 3, "metrics": [
        {"name": "MinADEK", "k_to_report": [1, 2], "aggregators": [{"name": "RowMean"}]}]})
    assert resolve_prediction_config(custom) is custom
    assert resolve_prediction_config().seconds == 6  # the devkit's predict_2020_icra
    with pytest.raises(UsageError) as caught:
        PredictionConfig.from_dict({"seconds": 6, "metrics": ["MinADEK"]})
    assert str(caught.value) == ("config: metrics[0]: name must be one of MinADEK, MinFDEK, MissRateTopK, "
                                 "OffRoadRate, got None")


def test_an_empty_submission_gives_typed_empty_tables(pred_out, tmp_path):
    """No record: the devkit's NaN means, and agents and modes tables of no row that keep their column types."""
    import polars as pl

    from nuparquet.evaluation.prediction import evaluate_prediction

    ours = evaluate_prediction(pred_out, write(tmp_path, []), split=SPLIT)
    assert ours.agents.height == ours.modes.height == 0
    assert ours.agents.schema["modes"] == ours.agents.schema["predicted_steps"] == pl.Int64
    assert ours.agents.schema["future_steps"] == pl.Int64
    assert [(name, ours.modes.schema[name]) for name in ("agent", "mode", "probability", "rank")] == [
        ("agent", pl.Int64), ("mode", pl.Int64), ("probability", pl.Float64), ("rank", pl.Int64)]


def test_attribute_slices_and_a_custom_split_hold_the_records_they_name(pred_out, pred_root, devkit, tmp_path):
    """--by attribute places an agent by its annotation's first attribute (the devkit's metrics of those records);
    a custom split of <dataroot>/<version>/splits.json is read from the dataset's version folder; the modes table
    names its columns."""
    from nuscenes.eval.prediction.compute_metrics import compute_metrics

    from nuparquet.evaluation.prediction import evaluate_prediction

    nusc = devkit[0]
    records = perturbed(devkit, 6, count=40)
    ours = evaluate_prediction(pred_out, write(tmp_path, records), split=SPLIT, by=("attribute",))
    attributes = {a["token"]: a["name"] for a in nusc.attribute}

    def first_attribute(record):
        ann = next(nusc.get("sample_annotation", t) for t in nusc.get("sample", record["sample"])["anns"]
                   if nusc.get("sample_annotation", t)["instance_token"] == record["instance"])
        return attributes[ann["attribute_tokens"][0]] if ann["attribute_tokens"] else ""

    labels = [first_attribute(r) for r in records]
    assert len({label for label in labels if label}) >= 2
    for row in ours.slices.iter_rows(named=True):
        members = [r for r, label in zip(records, labels) if (label or "none") == row["slice"]]
        assert row["agents"] == len(members) > 0, row["slice"]
        assert row["MinADEK_5"] == compute_metrics(members, devkit[1], devkit[2])["MinADEK"]["RowMean"][1]
    assert ours.modes.columns[:7] == ["agent", "mode", "probability", "rank", "ade_m", "fde_m", "max_distance_m"]
    # a custom split naming the records' scenes, in the version folder of the dataset's dataroot
    scenes = sorted({nusc.get("scene", nusc.get("sample", r["sample"])["scene_token"])["name"] for r in records})
    splits_file = pred_root / SYNTH_VERSION / "splits.json"
    assert not splits_file.exists()
    try:
        splits_file.write_text(json.dumps({"mine": scenes}))
        custom = evaluate_prediction(pred_out, write(tmp_path, records), split="mine")
    finally:
        splits_file.unlink()
    assert json.dumps(custom.metrics) == json.dumps(ours.metrics)
