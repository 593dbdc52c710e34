"""The output plan: tile placement for rows of different lengths, and which camera row fills which tile."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from nuparquet.rendering.mosaic import compose, match_frames_by_time, mosaic_size, tile_origins, time_steps_us
from nuparquet.rendering.plan import camera_rows_per_output, tile_size


def test_rows_of_different_lengths_size_the_picture_by_the_longest_and_centre_the_shorter():
    assert mosaic_size((4, 3), 100, 50) == (400, 100)
    # Front row of four at x = 0, 100, 200, 300; back row of three shifted by half a tile.
    assert tile_origins((4, 3), 100, 50) == [(0, 0), (100, 0), (200, 0), (300, 0), (50, 50), (150, 50), (250, 50)]
    assert tile_origins((3, 3), 10, 5) == [(0, 0), (10, 0), (20, 0), (0, 5), (10, 5), (20, 5)]


def test_compose_places_each_tile_and_leaves_gaps_black():
    tiles = [np.full((2, 3, 3), value, np.uint8) for value in (10, 20, 30)]
    picture = compose([tiles[0], tiles[1], None, tiles[2]], (2, 2), 3, 2)
    assert picture.shape == (4, 6, 3)
    assert (picture[:2, :3] == 10).all() and (picture[:2, 3:] == 20).all()
    assert (picture[2:, :3] == 0).all() and (picture[2:, 3:] == 30).all()
    odd = compose(tiles, (2, 1), 3, 2)  # the back row's one tile centred: x = 3 // 2 = 1
    assert (odd[2:, 1:4] == 30).all() and (odd[2:, 0] == 0).all() and (odd[2:, 4:] == 0).all()
    assert compose([tiles[0]], (1,), 3, 2) is tiles[0]  # one tile: the picture is the tile


def _cameras() -> pl.DataFrame:
    """Two cameras over two samples (s1 then s2), sorted by channel then time, with one sweep of A."""
    rows = [  # channel, sample, timestamp, keyframe
        ("A", "s1", 100, True), ("A", "s2", 140, False), ("A", "s2", 200, True),
        ("B", "s1", 90, True), ("B", "s2", 190, True),
    ]
    return pl.DataFrame(rows, schema=["channel", "sample_token", "timestamp", "is_key_frame"], orient="row")


def test_one_channel_shows_every_row_in_order():
    times, rows = camera_rows_per_output(_cameras().filter(pl.col("channel") == "A"), pl.DataFrame(), ["A"],
                                         mosaic=False, all_frames=True, fps=12.0)
    assert rows.tolist() == [[0], [1], [2]]
    assert times.tolist() == [100.0, 140.0, 200.0]


def test_keyframe_mosaic_has_one_output_per_sample_in_time_order_with_each_cameras_keyframe():
    samples = pl.DataFrame({"token": ["s2", "s1"], "timestamp": [200, 100]})
    times, rows = camera_rows_per_output(_cameras(), samples, ["B", "A", "C"], mosaic=True, all_frames=False,
                                         fps=2.0)
    # Columns follow the layout order (B, A, C); C has no frames; the sweep of A (row 1) is never used.
    assert rows.tolist() == [[3, 0, -1], [4, 2, -1]]
    assert times.tolist() == [90.0, 190.0]  # each sample's earliest keyframe


def test_compose_returns_a_uint8_picture_and_names_a_tile_of_the_wrong_size():
    tiles = [np.full((2, 3, 3), 7, np.uint8), None]
    assert compose(tiles, (2,), 3, 2).dtype == np.uint8
    with pytest.raises(ValueError, match="tile is 4x2, expected 3x2"):
        compose([np.zeros((2, 4, 3), np.uint8), None], (2,), 3, 2)


def test_tile_size_is_the_largest_camera_scaled_and_rounded_at_least_two_pixels():
    cameras = pl.DataFrame({"width": [1600, 1224, 2048], "height": [900, 1024, 864]})
    assert tile_size(cameras, 0.5) == (1024, 512)  # widest 2048, tallest 1024: from different cameras
    assert tile_size(cameras, 0.1005) == (206, 103)  # 205.8 and 102.9: rounded, not truncated
    assert tile_size(cameras, 0.0001) == (2, 2)


def test_time_steps_follow_the_devkit_clock_until_it_passes_the_last_sample():
    """devkit render_scene: from the first keyframe, add 1/freq s while the time is before the last one."""
    assert time_steps_us(1_000_000, 2_000_000, 10.0).tolist() == [1_000_000.0 + 100_000 * k for k in range(1, 11)]
    assert time_steps_us(0, 1, 2.0).tolist() == [500_000.0]
    none = time_steps_us(5, 5, 2.0)
    assert none.dtype == np.float64 and len(none) == 0


def test_match_frames_by_time_with_no_frame_one_frame_ties_and_the_start_index():
    assert match_frames_by_time(np.array([]), 0, np.array([1.0, 2.0])).tolist() == [-1, -1]
    assert match_frames_by_time(np.array([5.0]), 0, np.array([1.0, 10.0])).tolist() == [0, 0]
    # the first frame at or after each time (a tie shows the frame at that time), never before start_index, and
    # the last frame once every frame is older
    got = match_frames_by_time(np.array([10.0, 20.0, 30.0]), 1, np.array([5.0, 20.0, 21.0, 99.0]))
    assert got.dtype == np.int64 and got.tolist() == [1, 1, 2, 2]


def test_all_frames_mosaic_matches_each_camera_on_the_clock():
    """Clock 4 Hz from s1 (t = 0) to s2 (t = 1 s): 0.25, 0.5, 0.75, 1.0 s. A starts at its s1 keyframe; B has no
    s1 keyframe and starts at its first row; C has no frame (its tiles stay empty, and D after it is still
    filled); D has one frame."""
    rows = [  # channel, sample, timestamp (us), keyframe; sorted by channel then time
        ("A", "s1", 0, True), ("A", "s2", 400_000, False), ("A", "s2", 1_000_000, True),
        ("B", "s2", 500_000, False), ("B", "s2", 900_000, True),
        ("D", "s1", 0, True),
    ]
    cameras = pl.DataFrame(rows, schema=["channel", "sample_token", "timestamp", "is_key_frame"], orient="row")
    samples = pl.DataFrame({"token": ["s1", "s2"], "timestamp": [0, 1_000_000]})
    times, got = camera_rows_per_output(cameras, samples, ["B", "C", "A", "D"], mosaic=True, all_frames=True, fps=4.0)
    assert times.dtype == np.float64 and times.tolist() == [250_000.0, 500_000.0, 750_000.0, 1_000_000.0]
    assert got.dtype == np.int64
    assert got.tolist() == [[3, -1, 1, 5], [3, -1, 2, 5], [4, -1, 2, 5], [4, -1, 2, 5]]


def test_all_frames_mosaic_does_not_depend_on_the_order_of_the_sample_table():
    """The clock runs from the earliest sample to the latest whatever order the sample rows come in (a scene's
    samples read back from a dataset sorted otherwise, or a table in file order that is not time order)."""
    cameras = pl.DataFrame([("A", "s1", 0, True), ("A", "s2", 400_000, False), ("A", "s3", 1_000_000, True)],
                           schema=["channel", "sample_token", "timestamp", "is_key_frame"], orient="row")
    in_order = pl.DataFrame({"token": ["s1", "s2", "s3"], "timestamp": [0, 500_000, 1_000_000]})
    expected = camera_rows_per_output(cameras, in_order, ["A"], mosaic=True, all_frames=True, fps=4.0)
    assert expected[0].tolist() == [250_000.0, 500_000.0, 750_000.0, 1_000_000.0]
    for shuffled in (in_order.reverse(), in_order[[1, 2, 0]]):
        times, rows = camera_rows_per_output(cameras, shuffled, ["A"], mosaic=True, all_frames=True, fps=4.0)
        assert times.tolist() == expected[0].tolist() and rows.tolist() == expected[1].tolist() == [[1], [2], [2], [2]]


def test_output_times_are_float64_microseconds_for_one_camera_and_the_keyframe_mosaic():
    one, _ = camera_rows_per_output(_cameras().filter(pl.col("channel") == "A"), pl.DataFrame(), ["A"],
                                    mosaic=False, all_frames=True, fps=12.0)
    samples = pl.DataFrame({"token": ["s2", "s1"], "timestamp": [200, 100]})
    keyframes, _ = camera_rows_per_output(_cameras(), samples, ["A", "B"], mosaic=True, all_frames=False, fps=2.0)
    assert one.dtype == np.float64 and keyframes.dtype == np.float64


def test_a_row_tile_shows_the_token_and_time_of_its_row_and_nothing_for_no_row_or_no_tokens():
    """`RowTile.shows` (the frame index's entry for each output): the row's sample_data token and timestamp, None
    where the tile shows no row (-1), and None for a source without tokens."""
    from nuparquet.rendering.plan import RowTile

    tile = RowTile()
    tile.rows = np.array([1, -1, 0, 1])
    tile.tokens = ("first", "second")
    tile.timestamps_us = np.array([1_000, 2_000], np.int64)
    assert [tile.shows(t) for t in range(4)] == [("second", 2_000), None, ("first", 1_000), ("second", 2_000)]
    assert [tile.key(t) for t in range(4)] == [1, None, 0, 1]
    untokened = RowTile()
    untokened.rows = np.array([0, -1])
    assert [untokened.shows(t) for t in range(2)] == [None, None]
