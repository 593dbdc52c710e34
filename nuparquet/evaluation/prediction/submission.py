"""A prediction submission as nuscenes-devkit reads it: a JSON list of `Prediction.serialize()` records
({"instance", "sample", "prediction": modes x steps x 2 metres, "probabilities": one per mode}), each checked as
`Prediction.is_valid` checks it and, beyond it, for what the devkit would mis-evaluate (a NaN, no mode, no step, a
state other than x, y): InputError naming the record (index, instance, sample) and the field."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nuparquet.errors import InputError, UsageError

MAX_NUMBER_OF_MODES = 25  # the devkit's data_classes.MAX_NUMBER_OF_MODES
FIELDS = ("instance", "sample", "prediction", "probabilities")


@dataclass
class Submission:
    """The records in file order. prediction[i]: (M, T, 2) float64; probabilities[i]: (M,) as the devkit's
    `np.array` of the list makes it (int64 when every value is an integer: its argsort breaks ties on that)."""

    instances: list[str]
    samples: list[str]
    prediction: list[np.ndarray]
    probabilities: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.instances)


def where(i: int, record: dict) -> str:
    return f"record {i} (instance {record.get('instance')!r}, sample {record.get('sample')!r})"


def read_submission(path: str | Path) -> Submission:
    """The submission at `path`; UsageError when it is not a readable JSON file, InputError for a record the
    devkit would refuse or mis-evaluate."""
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"--results {path}: no such file (a prediction submission is a JSON list of Prediction "
                         "records)")
    try:
        content = json.loads(path.read_bytes())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: cannot be read as JSON ({exc})") from exc
    if not isinstance(content, list):
        raise InputError(f"{path}: a prediction submission is a JSON list of records, not {type(content).__name__}")
    return parse_records(content, str(path))


def parse_records(records: list, source: str = "submission") -> Submission:
    """Check and convert the submission's records (see the module docstring)."""
    out = Submission([], [], [], [])
    for i, record in enumerate(records):
        if not isinstance(record, dict):
            raise InputError(f"{source}: record {i} is not an object")
        here = f"{source}: {where(i, record)}"
        missing = [f for f in FIELDS if f not in record]
        if missing:
            raise InputError(f"{here}: missing field {', '.join(missing)}")
        for name in ("instance", "sample"):
            if not isinstance(record[name], str):
                raise InputError(f"{here}: {name} must be a token (a string), not {record[name]!r}")
        prediction = _array(record["prediction"], here, "prediction")
        probabilities = _array(record["probabilities"], here, "probabilities")
        if prediction.ndim != 3 or prediction.shape[2] != 2 or prediction.shape[0] == 0 or prediction.shape[1] == 0:
            raise InputError(f"{here}: prediction must be modes x steps x 2 (x, y metres) with at least one mode and "
                             f"one step, got shape {prediction.shape}")
        if prediction.shape[0] > MAX_NUMBER_OF_MODES:
            raise InputError(f"{here}: prediction has {prediction.shape[0]} modes, more than the devkit's "
                             f"{MAX_NUMBER_OF_MODES}")
        if probabilities.ndim != 1 or len(probabilities) != prediction.shape[0]:
            raise InputError(f"{here}: probabilities must hold one number per mode ({prediction.shape[0]}), got "
                             f"shape {probabilities.shape}")
        for name, values in (("prediction", prediction), ("probabilities", probabilities)):
            if not np.isfinite(values).all():
                bad = np.argwhere(~np.isfinite(values))[0]
                raise InputError(f"{here}: {name}{list(map(int, bad))} is {values[tuple(bad)]} (numbers must be "
                                 "finite)")
        out.instances.append(record["instance"])
        out.samples.append(record["sample"])
        out.prediction.append(prediction.astype(np.float64, copy=False))
        out.probabilities.append(probabilities)
    return out


def _array(value, here: str, name: str) -> np.ndarray:
    """The devkit's `np.array(content[name])`, refused unless it is numbers (no bools, strings or nulls)."""
    if not isinstance(value, list):
        raise InputError(f"{here}: {name} must be a list of numbers, not {type(value).__name__}")
    try:
        array = np.array(value)
    except ValueError as exc:
        raise InputError(f"{here}: {name} is not a rectangular array of numbers ({exc})") from None
    if array.dtype.kind not in "if" or (array.dtype.kind == "i" and array.dtype != np.int64):
        if array.size == 0:
            return array.astype(np.float64)
        raise InputError(f"{here}: {name} must hold numbers only (no strings, booleans or nulls)")
    return array

