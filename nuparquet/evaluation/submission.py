"""Reading and checking a nuScenes detection submission (`results.json`):

    {"meta": {...}, "results": {sample_token: [{"sample_token": sample_token, "translation": [x, y, z],
        "size": [w, l, h], "rotation": [w, x, y, z], "velocity": [vx, vy], "detection_name": "car",
        "detection_score": 0.9, "attribute_name": "vehicle.moving"}, ...], ...}}

The file is parsed by DuckDB's typed JSON reader straight into Arrow columns (a val submission of 300k boxes
is ~140 MB of JSON: Python's json module needs several times longer and builds a dict per box). When DuckDB
refuses the file (a wrong type, a duplicate sample, not JSON at all), it is read again with Python's json
module, which names the sample and the box at fault. Like DuckDB's reader, numbers written as JSON strings
are read as numbers.

What is refused, each problem naming the sample token and the box index (its position in the sample's list):
a missing "meta" or "results", a sample listed twice, a box that is not an object or lacks a field, lists of
the wrong length, non-finite numbers (NaN velocities excepted: the devkit evaluates them, as "no velocity",
which `cummean` skips), sizes that are not positive (the devkit's scale IoU asserts it), a zero rotation
quaternion, unknown class or attribute names (the devkit's vocabulary), more boxes in a sample than the
configuration allows, a box whose "sample_token" is not the sample it is listed under (the devkit would
match it against that other sample's ground truth), and (`check_samples`) samples missing from or foreign
to the evaluated split. Extra fields of a box are ignored, as by the devkit, except "num_pts" (the devkit
reads it: a prediction claiming 0 points is filtered out like a ground-truth box without points).

The tracking submission (`TRACKING_FIELDS`) is read by the same code: its boxes carry "tracking_id",
"tracking_name" and "tracking_score" instead of the detection fields, and its sizes need not be positive (the
tracking metrics never use them); `read_boxes` returns the columns of either kind (`SubmittedBoxes`).

Longer than our ~300-line norm on purpose: every check a submission goes through, and the message that names the
sample and the box, stand together so the rules can be read in one place.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from nuparquet.errors import InputError, UsageError
from nuparquet.evaluation.classes import ATTRIBUTE_NAMES, DETECTION_NAMES
from nuparquet.geometry.cuboids import CuboidRows, Cuboids

MAX_LISTED = 10  # problems named in one error message
VECTOR_FIELDS = {"translation": 3, "size": 3, "rotation": 4, "velocity": 2}


@dataclass(frozen=True)
class BoxFields:
    """What one kind of submission box holds besides the box: its class field (`name`), its score field, further
    string fields (`labels`: required strings, or integers read as their decimal text where `integer_labels`
    allows), and whether its size must be positive (the detection scale error divides by the volume)."""

    kind: str
    name: str
    score: str
    labels: tuple[str, ...]
    positive_size: bool
    integer_labels: tuple[str, ...] = ()

    @property
    def required(self) -> tuple[str, ...]:
        return ("sample_token", *VECTOR_FIELDS, self.name, self.score, *self.labels)

    def duckdb_struct(self) -> str:
        # a field that may be a string or an integer is read as JSON text, its kind checked after (a VARCHAR would
        # take a list or an object as its text)
        strings = ", ".join(f"{name} {'JSON' if name in self.integer_labels else 'VARCHAR'}"
                            for name in (self.name, *self.labels))
        return ("STRUCT(sample_token VARCHAR, translation DOUBLE[], size DOUBLE[], rotation DOUBLE[], velocity DOUBLE[], "
                f"{strings}, {self.score} DOUBLE, num_pts BIGINT)")


DETECTION_FIELDS = BoxFields("detection", "detection_name", "detection_score", ("attribute_name",), positive_size=True)
# the devkit's TrackingBox: tracking_id is documented as a string; trackers that write integers are read as their text
TRACKING_FIELDS = BoxFields("tracking", "tracking_name", "tracking_score", ("tracking_id",), positive_size=False,
                            integer_labels=("tracking_id",))
REQUIRED_FIELDS = DETECTION_FIELDS.required


@dataclass(frozen=True)
class SubmittedBoxes(CuboidRows):
    """A submission of either kind as aligned arrays, boxes in file order (samples in the order of the file's keys,
    each sample's boxes in list order: the devkit's `EvalBoxes.all` order, which decides ties in score).

    cuboids: (N,) the boxes, global (`translation_m`, `size_wlh_m` [width, length, height], `rotation_wxyz`).
    meta: the file's "meta" object. sample_tokens: (S,) the samples, in file order.
    box_sample: (N,) int64 index into sample_tokens; box_index: (N,) int64 position in the sample's list.
    velocity_mps: (N, 2) global frame. class_name: (N,) str (detection_name / tracking_name); score: (N,) float64;
    labels: {field: (N,) str} the kind's further string fields (attribute_name, '' for none / tracking_id);
    num_pts: (N,) int64, -1 where the box does not say (the devkit's default)."""

    unaligned: ClassVar[tuple[str, ...]] = ("meta", "sample_tokens")

    meta: dict
    sample_tokens: np.ndarray
    box_sample: np.ndarray
    box_index: np.ndarray
    velocity_mps: np.ndarray
    class_name: np.ndarray
    score: np.ndarray
    labels: dict
    num_pts: np.ndarray

    def box_counts(self) -> np.ndarray:
        """(S,) boxes per sample."""
        return np.bincount(self.box_sample, minlength=len(self.sample_tokens))

    # a detection submission's fields by the devkit's names
    @property
    def detection_name(self) -> np.ndarray:
        return self.class_name

    @property
    def detection_score(self) -> np.ndarray:
        return self.score

    @property
    def attribute_name(self) -> np.ndarray:
        return self.labels["attribute_name"]


class _Problems:
    """Problems found while checking, each naming where; raised together as one InputError."""

    def __init__(self, path: Path):
        self.path = path
        self.lines: list[str] = []
        self.count = 0

    def add(self, message: str) -> None:
        self.count += 1
        if len(self.lines) < MAX_LISTED:
            self.lines.append(message)

    def add_boxes(self, sub_tokens, box_sample, box_index, rows: np.ndarray, what: str) -> None:
        for row in rows[:MAX_LISTED]:
            self.add(f"sample {sub_tokens[box_sample[row]]} box {int(box_index[row])}: {what}")
        self.count += max(0, len(rows) - MAX_LISTED)

    def raise_if_any(self) -> None:
        if self.count:
            more = f"\n  ... and {self.count - len(self.lines)} more" if self.count > len(self.lines) else ""
            raise InputError(f"{self.path}: {self.count} problem(s) in the submission:\n  "
                             + "\n  ".join(self.lines) + more)


def read_submission(path: str | Path, *, max_boxes_per_sample: int | None = None,
                    class_names: Sequence[str] = DETECTION_NAMES,
                    attribute_names: Sequence[str] = ATTRIBUTE_NAMES) -> SubmittedBoxes:
    """Read and check the detection submission at `path` (see the module docstring); InputError listing the
    problems. `class_names`, `attribute_names`: what a box may name (the configuration's taxonomy);
    `max_boxes_per_sample`: the configuration's limit.
    """
    return read_boxes(path, DETECTION_FIELDS, max_boxes_per_sample=max_boxes_per_sample,
                      class_names=class_names, attribute_names=attribute_names)


def read_boxes(path: str | Path, fields: BoxFields, *, max_boxes_per_sample: int | None = None,
               class_names: Sequence[str], attribute_names: Sequence[str] = ATTRIBUTE_NAMES) -> SubmittedBoxes:
    """Read and check a submission of the kind `fields` describes (DETECTION_FIELDS, TRACKING_FIELDS)."""
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"--results {path}: no such file")
    try:
        submission = _read_with_duckdb(path, fields)
    except _Unreadable:
        submission = _read_boxes_with_python(path, fields)
    _check_boxes(submission, path, max_boxes_per_sample, class_names, fields, attribute_names)
    return submission


def check_samples(submission: SubmittedBoxes, expected_tokens: Sequence[str], *, split: str, path: str | Path,
                  allow_extra: bool = False) -> None:
    """The devkit's "Samples in split doesn't match samples in predictions", naming the samples: every sample
    of the split must be in the submission (with an empty list if nothing was detected), and no other (unless
    `allow_extra`: a custom split, where the devkit picks the split's samples out of the submission)."""
    given = set(submission.sample_tokens.tolist())
    expected = set(expected_tokens)
    missing = [token for token in expected_tokens if token not in given]
    extra = [] if allow_extra else [token for token in submission.sample_tokens.tolist() if token not in expected]
    if not missing and not extra:
        return
    parts = []
    if missing:
        parts.append(f"{len(missing)} sample(s) of split {split} missing from the submission (give an empty list "
                     f"where nothing was detected): {', '.join(missing[:MAX_LISTED])}"
                     + (", ..." if len(missing) > MAX_LISTED else ""))
    if extra:
        parts.append(f"{len(extra)} sample(s) not in split {split}: {', '.join(extra[:MAX_LISTED])}"
                     + (", ..." if len(extra) > MAX_LISTED else ""))
    raise InputError(f"{path}: " + "; ".join(parts))


def restricted_to_split(sub: SubmittedBoxes, sample_tokens: np.ndarray) -> SubmittedBoxes:
    """A custom split (devkit `load_prediction_of_sample_tokens`): the split's samples only, in their order."""
    position = {token: i for i, token in enumerate(sub.sample_tokens.tolist())}
    keep = np.array([position[t] for t in sample_tokens.tolist()], dtype=np.int64)
    new_index = np.full(len(sub.sample_tokens), -1, dtype=np.int64)
    new_index[keep] = np.arange(len(keep))
    rows = np.flatnonzero(new_index[sub.box_sample] >= 0)
    rows = rows[np.argsort(new_index[sub.box_sample[rows]], kind="stable")]
    return replace(sub.take(rows), sample_tokens=sub.sample_tokens[keep], box_sample=new_index[sub.box_sample[rows]])


class _Unreadable(Exception):
    """DuckDB's typed reader refused the file: read it again with Python to say why."""


def _read_with_duckdb(path: Path, fields: BoxFields) -> SubmittedBoxes:
    import duckdb
    import polars as pl

    size = path.stat().st_size
    query = (f"SELECT json_type(meta) AS meta_type, CAST(meta AS VARCHAR) AS meta, "
             f"results IS NULL AS no_results, map_keys(results) AS samples, map_values(results) AS boxes "
             f"FROM read_json($path, format='unstructured', maximum_object_size={max(size + 1024, 1 << 24)}, "
             f"columns={{'meta': 'JSON', 'results': 'MAP(VARCHAR, {fields.duckdb_struct()}[])'}})")
    connection = duckdb.connect()
    try:
        relation = connection.sql(query, params={"path": str(path)})
        # Arrow's C stream straight into polars: no pyarrow loaded (0.15 s), and none of its to_numpy, which
        # loads pandas (0.25 s); older DuckDB without the stream interface goes through pyarrow
        table = pl.DataFrame(relation) if hasattr(relation, "__arrow_c_stream__") else pl.from_arrow(relation.arrow())
    except duckdb.Error as exc:
        raise _Unreadable(str(exc)) from exc
    finally:
        connection.close()
    if table.height != 1:
        raise _Unreadable("not one JSON object")
    if table["meta_type"][0] != "OBJECT" or table["no_results"][0]:
        raise _Unreadable("no meta or results object")
    meta = json.loads(table["meta"][0])
    tokens = table["samples"].explode().drop_nulls().to_numpy().astype(object)
    per_sample = table["boxes"].explode()  # (S,) list<struct> (null: a sample given null)
    if len(tokens) == 0:
        per_sample = per_sample.clear()
    if per_sample.null_count():
        raise _Unreadable("a sample's boxes are null")
    counts = per_sample.list.len().to_numpy().astype(np.int64)
    boxes = per_sample.filter(pl.Series(counts > 0)).explode()  # (N,) struct
    if boxes.null_count():
        raise _Unreadable("a box is null")
    unnested = boxes.struct.unnest()
    columns = {}
    for name, width in VECTOR_FIELDS.items():
        field = unnested[name]
        if field.null_count() or (field.list.len() != width).any():
            raise _Unreadable(f"a {name} missing or of the wrong length")
        values = field.explode()
        if values.null_count():
            raise _Unreadable(f"a {name} holds null")
        columns[name] = values.to_numpy().astype(np.float64).reshape(-1, width)
    for name in ("sample_token", fields.name, fields.score, *fields.labels):
        if unnested[name].null_count():
            raise _Unreadable(f"a box lacks {name}")
    labels = {}
    for name in fields.labels:
        column = unnested[name]
        if name in fields.integer_labels:  # JSON text: a string literal, decoded, or an integer, as written
            quoted = column.str.starts_with('"')
            if not (quoted | column.str.contains(r"^-?[0-9]+$")).all():
                raise _Unreadable(f"a {name} is neither a string nor an integer")
            text = column.to_numpy().astype(object)
            if quoted.any():
                text[quoted.to_numpy()] = np.array(column.filter(quoted).str.json_decode(pl.String).to_list(), object)
            labels[name] = text
        else:
            labels[name] = column.to_numpy().astype(object)
    box_sample = np.repeat(np.arange(len(tokens), dtype=np.int64), counts)
    named = unnested["sample_token"].to_numpy().astype(object)
    if len(named) and (named != tokens[box_sample]).any():
        raise _Unreadable("a box names another sample")
    return SubmittedBoxes(
        meta=meta, sample_tokens=tokens, box_sample=box_sample,
        box_index=np.arange(len(box_sample), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts),
        cuboids=Cuboids(columns["translation"], columns["size"], columns["rotation"]), velocity_mps=columns["velocity"],
        class_name=unnested[fields.name].to_numpy().astype(object),
        score=unnested[fields.score].to_numpy().astype(np.float64),
        labels=labels, num_pts=unnested["num_pts"].fill_null(-1).to_numpy().astype(np.int64),
    )


def _unique_keys(pairs):
    """json object_pairs_hook: a dict, or a marker naming the first key given twice."""
    seen = {}
    for key, value in pairs:
        if key in seen:
            return _Duplicate(key)
        seen[key] = value
    return seen


class _Duplicate:
    def __init__(self, key: str):
        self.key = key


def _read_with_python(path: Path) -> SubmittedBoxes:
    """The strict reader of a detection submission (`_read_boxes_with_python`)."""
    return _read_boxes_with_python(path, DETECTION_FIELDS)


def _read_boxes_with_python(path: Path, fields: BoxFields) -> SubmittedBoxes:
    """The strict reader: every problem of the file found and named (slow; used when DuckDB refused it)."""
    try:
        data = json.loads(path.read_bytes(), object_pairs_hook=_unique_keys)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc})") from exc
    except RecursionError as exc:
        raise InputError(f"{path}: nested too deeply to be a submission") from exc
    problems = _Problems(path)
    if isinstance(data, _Duplicate):
        raise InputError(f"{path}: key {data.key!r} given twice at the top level")
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object with \"meta\" and \"results\", got {type(data).__name__}")
    if "results" not in data or not isinstance(data["results"], (dict, _Duplicate)):
        raise InputError(f"{path}: no \"results\" object (the {fields.kind} format: "
                         "{\"meta\": {...}, \"results\": {sample_token: [box, ...]}})")
    if not isinstance(data.get("meta"), dict):
        raise InputError(f"{path}: no \"meta\" object (the {fields.kind} format: {{\"meta\": {{\"use_camera\": ..., "
                         "\"use_lidar\": ..., ...}}, \"results\": {...}})")
    results = data["results"]
    if isinstance(results, _Duplicate):
        raise InputError(f"{path}: sample {results.key} is listed twice in \"results\"")
    strings = ("sample_token", fields.name, *fields.labels)
    tokens, box_sample, box_index = [], [], []
    values: dict[str, list] = {name: [] for name in (*fields.required, "num_pts")}
    for sample, boxes in results.items():
        s = len(tokens)
        tokens.append(sample)
        if not isinstance(boxes, list):
            problems.add(f"sample {sample}: expected a list of boxes, got {_kind(boxes)}")
            continue
        for i, box in enumerate(boxes):
            where = f"sample {sample} box {i}"
            if isinstance(box, _Duplicate):
                problems.add(f"{where}: field {box.key!r} given twice")
                continue
            if not isinstance(box, dict):
                problems.add(f"{where}: expected an object, got {_kind(box)}")
                continue
            missing = [name for name in fields.required if name not in box]
            if missing:
                problems.add(f"{where}: missing {', '.join(missing)}")
                continue
            ok = True
            for name, width in VECTOR_FIELDS.items():
                vector = box[name]
                if not isinstance(vector, list) or len(vector) != width or not all(_is_number(v) for v in vector):
                    problems.add(f"{where}: {name} must be a list of {width} numbers, got {_short(vector)}")
                    ok = False
            for name in strings:
                value = box[name]
                if name in fields.integer_labels and isinstance(value, int) and not isinstance(value, bool):
                    box[name] = str(value)  # as DuckDB's VARCHAR reads a JSON integer
                elif not isinstance(value, str):
                    also = " (or an integer)" if name in fields.integer_labels else ""
                    problems.add(f"{where}: {name} must be a string{also}, got {_short(value)}")
                    ok = False
            if isinstance(box["sample_token"], str) and box["sample_token"] != sample:
                problems.add(f"{where}: sample_token {box['sample_token']!r} is not the sample it is listed under")
                ok = False
            if not _is_number(box[fields.score]):
                problems.add(f"{where}: {fields.score} must be a number, got {_short(box[fields.score])}")
                ok = False
            num_pts = box.get("num_pts", -1)
            if isinstance(num_pts, bool) or not isinstance(num_pts, int):
                problems.add(f"{where}: num_pts must be an integer, got {_short(num_pts)}")
                ok = False
            if not ok:
                continue
            box_sample.append(s)
            box_index.append(i)
            for name in fields.required:
                values[name].append(box[name])
            values["num_pts"].append(num_pts)
    problems.raise_if_any()
    n = len(box_sample)

    def vectors(name: str) -> np.ndarray:
        return np.array(values[name], dtype=np.float64).reshape(n, VECTOR_FIELDS[name])

    return SubmittedBoxes(
        meta=data["meta"], sample_tokens=np.array(tokens, dtype=object),
        box_sample=np.array(box_sample, dtype=np.int64), box_index=np.array(box_index, dtype=np.int64),
        cuboids=Cuboids(vectors("translation"), vectors("size"), vectors("rotation")), velocity_mps=vectors("velocity"), class_name=np.array(values[fields.name], dtype=object),
        score=np.array(values[fields.score], dtype=np.float64),
        labels={name: np.array(values[name], dtype=object) for name in fields.labels},
        num_pts=np.array(values["num_pts"], dtype=np.int64),
    )


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _kind(value) -> str:
    kinds = {dict: "an object", list: "a list", str: "a string", type(None): "null"}
    return kinds.get(type(value), type(value).__name__)


def _short(value) -> str:
    text = json.dumps(value) if not isinstance(value, _Duplicate) else "an object with a repeated field"
    return text if len(text) <= 60 else text[:57] + "..."


def _check_boxes(sub: SubmittedBoxes, path: Path, max_boxes_per_sample: int | None, class_names: Sequence[str],
                 fields: BoxFields, attribute_names: Sequence[str] = ATTRIBUTE_NAMES) -> None:
    """The checks of the module docstring that need no dataset, vectorised over every box."""
    problems = _Problems(path)
    if max_boxes_per_sample is not None:
        counts = sub.box_counts()
        for s in np.flatnonzero(counts > max_boxes_per_sample)[:MAX_LISTED]:
            problems.add(f"sample {sub.sample_tokens[s]}: {int(counts[s])} boxes, more than the "
                         f"{max_boxes_per_sample} per sample the configuration allows")
    where = (sub.sample_tokens, sub.box_sample, sub.box_index)
    for name, values in (("translation", sub.translation_m), ("size", sub.size_wlh_m),
                         ("rotation", sub.rotation_wxyz)):
        problems.add_boxes(*where, np.flatnonzero(~np.isfinite(values).all(axis=1)), f"{name} is not finite")
    problems.add_boxes(*where, np.flatnonzero(np.isinf(sub.velocity_mps).any(axis=1)),
                       "velocity is infinite (NaN is allowed: no velocity estimate)")
    problems.add_boxes(*where, np.flatnonzero(~np.isfinite(sub.score)), f"{fields.score} is not finite")
    if fields.positive_size:
        problems.add_boxes(*where, np.flatnonzero(np.isfinite(sub.size_wlh_m).all(axis=1)
                                                  & (sub.size_wlh_m <= 0).any(axis=1)),
                           "size must be positive (the scale error divides by the volume)")
    problems.add_boxes(*where, np.flatnonzero((sub.rotation_wxyz == 0).all(axis=1)),
                       "rotation is the zero quaternion")
    vocabularies = [(sub.class_name, class_names, fields.name)]
    if "attribute_name" in fields.labels:
        vocabularies.append((sub.labels["attribute_name"], ("", *attribute_names), "attribute_name"))
    for column, valid, what in vocabularies:
        unknown = np.flatnonzero(~np.isin(column, np.array(list(valid), dtype=object)))
        if len(unknown):
            choices = ", ".join(repr(v) for v in valid)
            for row in unknown[:MAX_LISTED]:
                problems.add(f"sample {sub.sample_tokens[sub.box_sample[row]]} box {int(sub.box_index[row])}: "
                             f"unknown {what} {column[row]!r} (one of {choices})")
            problems.count += max(0, len(unknown) - MAX_LISTED)
    problems.raise_if_any()
