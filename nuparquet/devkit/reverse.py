"""The devkit's reverse indexes (`NuScenes.__make_reverse_index__`), each built on first use from the converted columns.

The devkit adds, at start-up, to every record of four tables:
- `sample_annotation['category_name']`: the category of the annotation's instance;
- `sample_data['sensor_modality']`, `['channel']`: of the calibrated sensor's sensor;
- `sample['data']` ({channel: keyframe sample_data token}, in sample_data file order: a later keyframe of the same
  channel replaces the value and keeps the key's place) and `sample['anns']` (annotation tokens in file order);
- `log['map_token']`: the map listing the log (the last such map, as the devkit's dict keeps).
Here each becomes a lookup built the first time a record of that table is built: the small tables' records, or
a few columns of the large ones read once and grouped with numpy (sample_annotation: token and sample_token;
sample_data: the keyframes' token, sample_token and calibrated_sensor_token).
"""

from __future__ import annotations

import functools

import numpy as np
import pyarrow.compute as pc

from nuparquet.devkit.columns import TokenIndex, getter, single_chunk, token_bytes
from nuparquet.devkit.tables import ConvertedTables, Table
from nuparquet.errors import InputError


class ReverseIndex:
    """Lookups behind the reverse-index fields of `tables` (the NuScenes' tables by name)."""

    def __init__(self, tables: dict[str, Table], source: ConvertedTables):
        self.tables = tables
        self.source = source

    @functools.cached_property
    def category_of_instance(self) -> dict[str, str]:
        """{instance token: category name}."""
        instances = self.tables["instance"]
        if not len(instances):
            return {}
        columns = instances.columns
        token, category = columns.getter("token"), columns.getter("category_token")
        categories = self.tables["category"]
        names: dict[str, str] = {}
        out = {}
        for i in range(len(instances)):
            category_token = category(i)
            if category_token not in names:
                names[category_token] = categories.record_of(category_token)["name"]
            out[token(i)] = names[category_token]
        return out

    @functools.cached_property
    def sensor_of_calibration(self) -> dict[str, tuple[str, str]]:
        """{calibrated_sensor token: (sensor modality, channel)}."""
        calibrations = self.tables["calibrated_sensor"]
        columns = calibrations.columns
        token, sensor = columns.getter("token"), columns.getter("sensor_token")
        sensors = self.tables["sensor"]
        out = {}
        for i in range(len(calibrations)):
            record = sensors.record_of(sensor(i))
            out[token(i)] = (record["modality"], record["channel"])
        return out

    @functools.cached_property
    def map_of_log(self) -> dict[str, str]:
        """{log token: token of the (last) map whose log_tokens list it}."""
        out = {}
        for record in self.tables["map"]:
            for log_token in record["log_tokens"]:
                out[log_token] = record["token"]
        return out

    @functools.cached_property
    def sample_links(self) -> SampleLinks:
        return SampleLinks(self)

    def annotation_categories(self) -> np.ndarray:
        """(A,) object array: the category name of every annotation, in file order."""
        rows = self.source.rows("sample_annotation")
        if not rows:
            return np.array([], dtype=object)
        instance_of = self.tables["instance"].columns.index.find_all(
            token_bytes(self.source.read("sample_annotation", ["instance_token"]).column("instance_token")))
        if (instance_of < 0).any():
            raise InputError("an annotation names an instance that is not in the instance table")
        instances = self.tables["instance"].columns
        category = instances.getter("category_token")
        categories = self.tables["category"]
        names = np.array([categories.record_of(category(i))["name"] for i in range(instances.length)] or [""],
                         dtype=object)
        return names[instance_of]


class SampleLinks:
    """`sample['anns']` and `sample['data']` of every sample, grouped once with numpy."""

    def __init__(self, index: ReverseIndex):
        samples = index.tables["sample"].columns.index
        n = len(index.tables["sample"])
        source = index.source

        annotations = source.read("sample_annotation", ["token", "sample_token"])
        sample_of = self._samples_of(samples, annotations, "sample_annotation")
        self._ann_order, self._ann_start = _group(sample_of, n)
        self._ann_token = getter(annotations.column("token"), share_strings=False)

        frames = source.read("sample_data", ["token", "sample_token", "is_key_frame", "calibrated_sensor_token"])
        frames = frames.filter(pc.equal(frames.column("is_key_frame"), True))
        sample_of = self._samples_of(samples, frames, "sample_data")
        self._data_order, self._data_start = _group(sample_of, n)
        self._data_token = getter(frames.column("token"), share_strings=False)
        calibration = single_chunk(frames.column("calibrated_sensor_token")).dictionary_encode()
        sensors = index.sensor_of_calibration
        channels = [sensors[token][1] for token in calibration.dictionary.to_pylist()]
        codes = calibration.indices.to_numpy(zero_copy_only=False)
        self._data_channel = [channels[c] for c in codes.tolist()]

    @staticmethod
    def _samples_of(samples: TokenIndex, table, name: str) -> np.ndarray:
        sample_of = samples.find_all(token_bytes(table.column("sample_token")))
        missing = np.flatnonzero(sample_of < 0)
        if len(missing):
            row = int(missing[0])
            raise InputError(f"{name} {table.column('token')[row].as_py()} names sample "
                             f"{table.column('sample_token')[row].as_py()}, which is not in the sample table")
        return sample_of

    def anns(self, sample: int) -> list[str]:
        token = self._ann_token
        return [token(j) for j in self._ann_order[self._ann_start[sample]:self._ann_start[sample + 1]].tolist()]

    def data(self, sample: int) -> dict[str, str]:
        out = {}
        token, channel = self._data_token, self._data_channel
        for j in self._data_order[self._data_start[sample]:self._data_start[sample + 1]].tolist():
            out[channel[j]] = token(j)
        return out

    def annotation_rows(self, sample: int) -> np.ndarray:
        """(K,) rows of `sample`'s annotations in the sample_annotation table, in file order."""
        return self._ann_order[self._ann_start[sample]:self._ann_start[sample + 1]]


def _group(owner: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows grouped by owner (stable: each group in row order) and the (n + 1,) start of each owner's group."""
    order = np.argsort(owner, kind="stable")
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(owner, minlength=n), out=start[1:])
    return order, start
