"""Bad submissions are refused with the sample (and the box) named, whichever reader sees the problem first
(DuckDB's typed reader, or Python's json module when DuckDB refuses the file)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation import evaluate
from nuparquet.evaluation.submission import _read_with_python, read_submission


@pytest.fixture(scope="module")
def good(submissions) -> dict:
    return json.loads(submissions["noisy"].read_text())


def eval_config_path():
    from importlib import resources

    return resources.files("nuparquet") / "data" / "detection_cvpr_2019.json"


def _write(tmp_path, content, name="bad.json"):
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def _first(data):
    token = next(iter(data["results"]))
    return token, data["results"][token]


def _edited(good, edit):
    data = copy.deepcopy(good)
    token, boxes = _first(data)
    edit(data, token, boxes)
    return data, token


BOX_PROBLEMS = [
    ("nan_translation", lambda b: b.__setitem__("translation", [float("nan"), 1.0, 2.0]), "translation is not finite"),
    ("inf_score", lambda b: b.__setitem__("detection_score", float("inf")), "detection_score is not finite"),
    ("inf_velocity", lambda b: b.__setitem__("velocity", [float("inf"), 0.0]), "velocity is infinite"),
    ("zero_size", lambda b: b.__setitem__("size", [0.0, 1.0, 1.0]), "size must be positive"),
    ("zero_rotation", lambda b: b.__setitem__("rotation", [0.0, 0.0, 0.0, 0.0]), "zero quaternion"),
    ("unknown_class", lambda b: b.__setitem__("detection_name", "tram"), "unknown detection_name 'tram'"),
    ("unknown_attribute", lambda b: b.__setitem__("attribute_name", "vehicle.flying"), "unknown attribute_name"),
    ("short_translation", lambda b: b.__setitem__("translation", [1.0, 2.0]), "translation must be a list of 3"),
    ("long_rotation", lambda b: b.__setitem__("rotation", [1.0, 0, 0, 0, 0]), "rotation must be a list of 4"),
    ("text_in_size", lambda b: b.__setitem__("size", [1.0, "wide", 1.0]), "size must be a list of 3 numbers"),
    ("missing_velocity", lambda b: b.pop("velocity"), "missing velocity"),
    ("missing_score", lambda b: b.pop("detection_score"), "missing detection_score"),
    ("other_sample", lambda b: b.__setitem__("sample_token", "f" * 32), "is not the sample it is listed under"),
    ("null_name", lambda b: b.__setitem__("detection_name", None), "detection_name must be a string"),
]


@pytest.mark.parametrize("case", BOX_PROBLEMS, ids=[c[0] for c in BOX_PROBLEMS])
def test_a_bad_box_is_named_by_sample_and_index(case, good, eval_out, tmp_path):
    _, edit, message = case

    def change(data, token, boxes):
        edit(boxes[2])

    data, token = _edited(good, change)
    path = _write(tmp_path, data)
    with pytest.raises(InputError) as caught:
        evaluate(eval_out, results=path, split="val")
    assert f"sample {token} box 2: " in str(caught.value) and message in str(caught.value)
    assert str(path) in str(caught.value)


def test_nan_velocity_is_accepted_as_the_devkit_does(good, tmp_path):
    data, _ = _edited(good, lambda d, t, boxes: boxes[0].__setitem__("velocity", [float("nan"), float("nan")]))
    submission = read_submission(_write(tmp_path, data))
    assert np.isnan(submission.velocity_mps[0]).all()


def test_missing_and_extra_samples_are_named(good, eval_out, tmp_path):
    data = copy.deepcopy(good)
    missing = list(data["results"])[3]
    del data["results"][missing]
    data["results"]["0" * 32] = []
    with pytest.raises(InputError) as caught:
        evaluate(eval_out, results=_write(tmp_path, data), split="val")
    text = str(caught.value)
    assert "missing from the submission" in text and missing in text
    assert "not in split val" in text and "0" * 32 in text


def test_more_boxes_than_the_configuration_allows(good, eval_out, tmp_path):
    config = json.loads((eval_config_path()).read_text())
    config["max_boxes_per_sample"] = 5
    config_file = _write(tmp_path, config, "config.json")
    token, boxes = _first(good)
    assert len(boxes) > 5
    with pytest.raises(InputError) as caught:
        evaluate(eval_out, results=_write(tmp_path, good), split="val", config_file=config_file)
    assert f"sample {token}: {len(boxes)} boxes, more than the 5 per sample" in str(caught.value)


@pytest.mark.parametrize("content, message", [
    ("not json at all", "not valid JSON"),
    ("[1, 2]", "expected a JSON object"),
    ('{"meta": {}}', 'no "results" object'),
    ('{"results": {}}', 'no "meta" object'),
    ('{"meta": {}, "results": {"a": [], "a": []}}', "sample a is listed twice"),
    ('{"meta": {}, "results": {"a": {"x": 1}}}', "sample a: expected a list of boxes"),
    ('{"meta": {}, "results": {"a": [3]}}', "sample a box 0: expected an object"),
])
def test_malformed_files_say_what_is_wrong(content, message, tmp_path):
    with pytest.raises(InputError, match=message):
        read_submission(_write(tmp_path, content))


def test_the_fast_and_the_strict_reader_agree(submissions):
    for path in submissions.values():
        fast, strict = read_submission(path), _read_with_python(path)
        for name in ("box_sample", "box_index", "translation_m", "size_wlh_m", "rotation_wxyz", "detection_score",
                     "num_pts"):
            np.testing.assert_array_equal(getattr(fast, name), getattr(strict, name))
        np.testing.assert_array_equal(fast.velocity_mps, strict.velocity_mps)  # NaN in the same places
        assert fast.sample_tokens.tolist() == strict.sample_tokens.tolist()
        assert fast.detection_name.tolist() == strict.detection_name.tolist()
        assert fast.attribute_name.tolist() == strict.attribute_name.tolist()
        assert fast.meta == strict.meta


def test_many_problems_are_counted_and_the_first_ones_listed(good, tmp_path):
    data = copy.deepcopy(good)
    for boxes in data["results"].values():
        for box in boxes:
            box["detection_name"] = "tram"
    with pytest.raises(InputError) as caught:
        read_submission(_write(tmp_path, data))
    total = sum(len(b) for b in data["results"].values())
    assert f"{total} problem(s)" in str(caught.value) and f"... and {total - 10} more" in str(caught.value)


def test_a_bad_value_is_quoted_whole_up_to_60_characters_and_cut_beyond(good, tmp_path):
    """The value quoted in a problem: its JSON text whole when at most 60 characters, else its first 57 and
    "..." (60 in all)."""
    for length, shown in ((58, None), (59, 57)):  # a string of n characters is n + 2 in JSON
        value = "n" * length
        text = json.dumps(value)
        data, token = _edited(good, lambda d, t, boxes: boxes[1].__setitem__("num_pts", value))
        with pytest.raises(InputError) as caught:
            read_submission(_write(tmp_path, data))
        quoted = text if shown is None else text[:shown] + "..."
        assert len(quoted) == 60
        assert f"sample {token} box 1: num_pts must be an integer, got {quoted}" in str(caught.value)
        assert (text in str(caught.value)) == (shown is None)


def test_a_missing_results_file_is_a_usage_error(eval_out, tmp_path):
    with pytest.raises(UsageError, match="no such file"):
        evaluate(eval_out, results=tmp_path / "nope.json", split="val")
