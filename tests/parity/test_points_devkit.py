"""lidar_points/ and radar_points/ of the real extract against the devkit's readers (`LidarPointCloud.from_file`,
`RadarPointCloud.from_file` with filters off and with its default filters): every point of all 972 keyframe files."""

from __future__ import annotations

import numpy as np
import polars as pl
import pyarrow.parquet as pq
import pytest



@pytest.fixture(scope="module")
def points_out(extract_points_out):
    return extract_points_out


def _frames(out, modality: str) -> pl.DataFrame:
    return (pl.scan_parquet(str(out / "frames" / "*.parquet"))
            .filter((pl.col("modality").cast(pl.String) == modality) & pl.col("is_key_frame"))
            .select("token", "filename").collect())


def _points_by_token(out, dataset: str) -> dict[str, pl.DataFrame]:
    table = pl.read_parquet(str(out / dataset / "*.parquet")).with_columns(pl.col("sample_data_token").cast(pl.String))
    return table.partition_by("sample_data_token", as_dict=True, maintain_order=True)


def test_every_lidar_point_is_bit_equal_to_devkit_from_file(points_out, extract_root):
    from nuscenes.utils.data_classes import LidarPointCloud

    frames = _frames(points_out, "lidar")
    by_token = _points_by_token(points_out, "lidar_points")
    assert len(frames) == len(by_token) == 81
    compared = 0
    for token, filename in frames.iter_rows():
        path = str(extract_root / filename)
        rows = by_token[(token,)]
        expected = LidarPointCloud.from_file(path).points  # (4, P) float32
        stored = np.stack([rows[c].to_numpy() for c in ("x", "y", "z", "intensity")])
        assert stored.dtype == np.float32 and stored.shape == expected.shape, filename
        assert np.array_equal(stored.view(np.uint32), expected.view(np.uint32)), filename  # bit for bit
        ring = np.fromfile(path, dtype=np.float32).reshape(-1, 5)[:, 4]
        assert np.array_equal(rows["ring"].to_numpy().astype(np.float32), ring), filename
        assert np.array_equal(rows["point_index"].to_numpy(), np.arange(expected.shape[1])), filename
        compared += expected.shape[1]
    total_bytes = sum((extract_root / f).stat().st_size for f in frames["filename"])
    assert compared == sum(len(r) for r in by_token.values()) == total_bytes // 20  # no point dropped or added


def test_every_radar_point_equals_devkit_with_filters_off_and_default_filters(points_out, extract_root):
    from nuscenes.utils.data_classes import RadarPointCloud

    frames = _frames(points_out, "radar")
    by_token = _points_by_token(points_out, "radar_points")
    assert len(frames) == len(by_token) == 405
    fields = [f.name for f in pq.read_schema(next((points_out / "radar_points").glob("*.parquet")))][6:-1]
    assert len(fields) == 18 and fields[:3] == ["x", "y", "z"]
    kept = 0
    for token, filename in frames.iter_rows():
        path = str(extract_root / filename)
        rows = by_token[(token,)]
        stored = np.stack([rows[c].to_numpy().astype(np.float64) for c in fields])
        RadarPointCloud.disable_filters()
        try:
            raw = RadarPointCloud.from_file(path).points
        finally:
            RadarPointCloud.default_filters()  # class state: restore for every other test
        filtered = RadarPointCloud.from_file(path).points
        assert np.array_equal(stored, raw, equal_nan=True), filename
        passes = rows["passes_default_filters"].to_numpy()
        assert np.array_equal(stored[:, passes], filtered, equal_nan=True), filename
        kept += int(passes.sum())
    assert 0 < kept < sum(len(r) for r in by_token.values())  # the filter removes some points, not all


def test_one_lidar_frame_lies_in_one_row_group_and_radar_frames_never_span_two(points_out):
    for dataset in ("lidar_points", "radar_points"):
        for part in sorted((points_out / dataset).glob("*.parquet")):
            file = pq.ParquetFile(part)
            seen: dict[str, int] = {}
            for g in range(file.num_row_groups):
                tokens = set(file.read_row_group(g, columns=["sample_data_token"]).column(0).to_pylist())
                for token in tokens:
                    assert token not in seen, f"{part.name}: frame {token} in row groups {seen[token]} and {g}"
                    seen[token] = g
                if dataset == "lidar_points":
                    assert len(tokens) == 1  # ~35k points: each frame alone, so a one-frame read reads only it


def test_ds_points_reads_exactly_one_row_group_per_real_lidar_frame(points_out):
    import nuparquet

    ds = nuparquet.open(points_out)
    index = ds._points_index("lidar_points")
    tokens = _frames(points_out, "lidar")["token"].to_list()
    assert all(index.groups_for_tokens([t]).sum() == 1 for t in tokens)


def test_manifest_lists_points_datasets_and_no_missing_keyframe_files(points_out):
    import json

    manifest = json.loads((points_out / "manifest.json").read_text())
    lidar = manifest["datasets"]["lidar_points"]
    assert lidar["missing_files"] == [] and lidar["frames"] == 81 and lidar["point_columns"] == 5
    assert lidar["rows"] == pl.scan_parquet(str(points_out / "lidar_points" / "*.parquet")).select(pl.len()).collect().item()
    assert manifest["datasets"]["radar_points"]["frames"] == 405
