"""Bad tracking submissions are refused naming the sample and the box (the detection reader's checks, with the
tracking fields), and what the devkit accepts is read as it reads it."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from nuparquet.errors import InputError
from nuparquet.evaluation.submission import TRACKING_FIELDS, _read_boxes_with_python, read_boxes
from nuparquet.evaluation.tracking import evaluate_tracking
from nuparquet.evaluation.tracking.config import TrackingConfig, resolve_tracking_config
from nuparquet.errors import UsageError

NAMES = resolve_tracking_config().tracking_names


@pytest.fixture(scope="module")
def good(eval_nusc) -> dict:
    import tracking_submissions

    return {"meta": tracking_submissions.META, "results": tracking_submissions.edge_submission(eval_nusc, seed=3)}


def _write(tmp_path, data, name="bad.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def _a_full_sample(data) -> str:
    return next(t for t, boxes in data["results"].items() if len(boxes) > 3)


PROBLEMS = [
    ("nan_translation", lambda b: b.__setitem__("translation", [float("nan"), 1.0, 2.0]), "translation is not finite"),
    ("nan_score", lambda b: b.__setitem__("tracking_score", float("nan")), "tracking_score is not finite"),
    ("unknown_class", lambda b: b.__setitem__("tracking_name", "barrier"), "unknown tracking_name 'barrier'"),
    ("short_size", lambda b: b.__setitem__("size", [1.0, 2.0]), "size must be a list of 3 numbers"),
    ("long_velocity", lambda b: b.__setitem__("velocity", [0.0, 0.0, 0.0]), "velocity must be a list of 2"),
    ("missing_id", lambda b: b.pop("tracking_id"), "missing tracking_id"),
    ("list_id", lambda b: b.__setitem__("tracking_id", [1]), "tracking_id must be a string (or an integer)"),
    ("zero_rotation", lambda b: b.__setitem__("rotation", [0.0, 0.0, 0.0, 0.0]), "zero quaternion"),
]


@pytest.mark.parametrize("case", PROBLEMS, ids=[c[0] for c in PROBLEMS])
def test_a_bad_box_is_named_by_sample_and_index(case, good, eval_out, tmp_path):
    _, edit, message = case
    data = copy.deepcopy(good)
    token = _a_full_sample(data)
    edit(data["results"][token][2])
    path = _write(tmp_path, data)
    with pytest.raises(InputError) as caught:
        evaluate_tracking(eval_out, path, None)
    assert f"sample {token} box 2: " in str(caught.value) and message in str(caught.value)


def test_a_missing_sample_is_named(good, eval_out, tmp_path):
    data = copy.deepcopy(good)
    missing = list(data["results"])[4]
    del data["results"][missing]
    with pytest.raises(InputError, match=f"missing from the submission.*{missing}"):
        evaluate_tracking(eval_out, _write(tmp_path, data), None)


def test_an_id_given_twice_in_one_sample_is_refused(good, eval_out, tmp_path):
    data = copy.deepcopy(good)
    token = _a_full_sample(data)
    boxes = data["results"][token]
    boxes[3]["tracking_id"] = boxes[1]["tracking_id"]
    with pytest.raises(InputError) as caught:
        evaluate_tracking(eval_out, _write(tmp_path, data), None)
    assert f"sample {token} box 3: tracking_id {boxes[1]['tracking_id']!r} already given to box 1" in str(caught.value)


def test_integer_ids_are_read_as_their_text_by_both_readers(good, tmp_path):
    data = copy.deepcopy(good)
    for boxes in data["results"].values():
        for i, box in enumerate(boxes):
            box["tracking_id"] = int(box["tracking_id"].encode().hex()[:6], 16) if i % 2 else box["tracking_id"]
    path = _write(tmp_path, data)
    fast = read_boxes(path, TRACKING_FIELDS, class_names=NAMES)
    strict = _read_boxes_with_python(path, TRACKING_FIELDS)
    assert fast.labels["tracking_id"].tolist() == strict.labels["tracking_id"].tolist()
    assert all(isinstance(v, str) for v in fast.labels["tracking_id"].tolist())
    np.testing.assert_array_equal(fast.score, strict.score)
    # the same ids as text evaluate the same
    as_text = copy.deepcopy(data)
    for boxes in as_text["results"].values():
        for box in boxes:
            box["tracking_id"] = str(box["tracking_id"])
    assert read_boxes(_write(tmp_path, as_text, "text.json"), TRACKING_FIELDS,
                      class_names=NAMES).labels["tracking_id"].tolist() == fast.labels["tracking_id"].tolist()


def test_a_config_must_name_the_devkits_tracking_classes():
    from importlib import resources

    content = json.loads((resources.files("nuparquet") / "data" / "tracking_nips_2019.json").read_text())
    TrackingConfig.from_dict(content)
    broken = copy.deepcopy(content)
    broken["class_range"].pop("car")
    with pytest.raises(UsageError, match="class_range must give a value for each of"):
        TrackingConfig.from_dict(broken)
    broken = copy.deepcopy(content)
    broken["metric_worst"].pop("amota")
    with pytest.raises(UsageError, match="metric_worst must give a value"):
        TrackingConfig.from_dict(broken)
