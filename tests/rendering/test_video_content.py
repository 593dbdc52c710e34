"""What the MP4s hold, decoded back with PyAV: frames in the order written, odd sizes padded by replicating
the last row/column (bottom/right), pixel values kept; and a rendered scene video whose frames are the
scene's camera images in the devkit's sample order."""

from __future__ import annotations

import av
import cv2
import numpy as np
import pytest

from nuparquet.cli.main import main
from nuparquet.rendering.video.video import VideoWriter
from conftest import IRREGULAR_EMPTY_VERSION


def decode(path) -> list[np.ndarray]:
    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]


def test_frames_come_back_in_order_with_odd_sizes_padded_at_the_bottom_and_right(tmp_path):
    width, height, n = 101, 51, 9
    frames = []
    for i in range(n):
        # Grey (no chroma to subsample), within video range (16..235) where RGB -> YUV -> RGB is near exact.
        grey = np.full((height, width, 3), 40 + 18 * i, np.uint8)
        grey[-1, :] = 220 - 10 * i  # the last row and column carry their own values
        grey[:, -1] = 60 + 10 * i
        frames.append(grey)
    path = tmp_path / "odd.mp4"
    with VideoWriter(path, width=width, height=height, fps=4, crf=0) as video:
        for frame in frames:
            video.write(frame)
    decoded = decode(path)
    assert len(decoded) == n
    for i, (got, sent) in enumerate(zip(decoded, frames)):
        assert got.shape == (height + 1, width + 1, 3)
        got = got.astype(int)
        # The picture itself, away from the sharp edges chroma subsampling blurs.
        assert np.abs(got[2:height - 2, 2:width - 2] - (40 + 18 * i)).max() <= 6, f"frame {i}"
        # Padding repeats the last row below it and the last column to its right (not black, not the first).
        assert np.abs(got[height, 2:width - 2] - (220 - 10 * i)).max() <= 6, f"frame {i} bottom padding"
        assert np.abs(got[2:height - 2, width] - (60 + 10 * i)).max() <= 6, f"frame {i} right padding"
        assert np.abs(got[:height, :width] - sent.astype(int)).mean() < 4  # colour-matrix rounding: ~(4, 1, 3)


def test_even_sizes_are_not_padded(tmp_path):
    path = tmp_path / "even.mp4"
    with VideoWriter(path, width=64, height=32, fps=2, crf=0) as video:
        for value in (30, 200):
            video.write(np.full((32, 64, 3), value, np.uint8))
    decoded = decode(path)
    assert [f.shape for f in decoded] == [(32, 64, 3)] * 2
    assert [abs(np.median(f) - value) <= 6 for f, value in zip(decoded, (30, 200))] == [True, True]


@pytest.mark.devkit
def test_a_rendered_video_shows_the_camera_images_in_the_devkits_sample_order(irregular_root, irregular_empty_out,
                                                                               devkit, tmp_path):
    """Annotations are empty, so each video frame is the resized camera image: frame k must be most like the
    k-th keyframe image of the devkit's sample chain, and 225 rows are padded to 226 with the last row."""
    nusc = devkit.NuScenes(version=IRREGULAR_EMPTY_VERSION, dataroot=str(irregular_root), verbose=False)
    scene = sorted(nusc.scene, key=lambda s: s["name"])[1]
    out = tmp_path / "scene.mp4"
    assert main(["render", str(irregular_empty_out), "--scene", scene["name"], "--channel", "CAM_BACK", "--out",
                 str(out), "--scale", "0.25", "--crf", "0", "--quiet"]) == 0
    images, token = [], scene["first_sample_token"]
    while token:
        sample = nusc.get("sample", token)
        source = cv2.imread(nusc.get_sample_data_path(sample["data"]["CAM_BACK"]))
        images.append(cv2.resize(source, (400, 225), interpolation=cv2.INTER_AREA).astype(int))
        token = sample["next"]
    decoded = decode(out)
    assert len(decoded) == len(images)
    for k, frame in enumerate(decoded):
        assert frame.shape == (226, 400, 3)
        errors = [np.abs(frame[:225].astype(int) - image).mean() for image in images]
        assert int(np.argmin(errors)) == k and errors[k] < 4, (k, errors)
        assert np.abs(frame[225].astype(int) - frame[224].astype(int)).mean() < 4  # replicated, not black


# --- the writer's small contract (each line below once let a plausible bug through) ---------------------------

from fractions import Fraction  # noqa: E402

from nuparquet.rendering.video.video import frame_rate, pad_to_even  # noqa: E402


@pytest.mark.parametrize("height, width", [(3, 5), (3, 4), (2, 5), (2, 4)])
def test_pad_to_even_replicates_the_last_row_and_column_only_where_odd(height, width):
    image = np.arange(height * width * 3, dtype=np.uint8).reshape(height, width, 3)
    padded = pad_to_even(image)
    assert padded.shape == (height + height % 2, width + width % 2, 3)
    np.testing.assert_array_equal(padded[:height, :width], image)  # nothing added at the top or left
    if height % 2:
        np.testing.assert_array_equal(padded[height, :width], image[-1])
    if width % 2:
        np.testing.assert_array_equal(padded[:height, width], image[:, -1])
    if not (height % 2 or width % 2):
        assert padded is image


def test_frame_rate_is_exact_for_ntsc_rates_and_refuses_non_positive_ones():
    assert frame_rate(12) == Fraction(12) and frame_rate(0.5) == Fraction(1, 2)
    assert frame_rate(30000 / 1001) == Fraction(30000, 1001)
    assert frame_rate(1 / 1002) == Fraction(1, 1001)  # denominators are bounded by NTSC's 1001
    for fps in (0, -2.0, float("nan")):
        with pytest.raises(ValueError, match="fps must be positive"):
            frame_rate(fps)


def test_writer_defaults_crf_bounds_nested_output_and_frame_count(tmp_path):
    path = tmp_path / "a" / "b" / "x.mp4"  # parents are created
    with VideoWriter(path, width=16, height=16) as video:  # default rate: 2 fps
        for _ in range(3):
            video.write(np.zeros((16, 16, 3), np.uint8))
        assert video.frames_written == 3
    with av.open(str(path)) as container:
        assert float(container.streams.video[0].average_rate) == 2.0
    VideoWriter(tmp_path / "ok.mp4", width=16, height=16, crf=51).abort()
    for crf in (52, -1):
        with pytest.raises(ValueError, match=f"crf must be in 0..51, got {crf}"):
            VideoWriter(tmp_path / "bad.mp4", width=16, height=16, crf=crf)


def test_writer_accepts_frames_already_padded_and_names_a_wrong_size(tmp_path):
    with VideoWriter(tmp_path / "p.mp4", width=15, height=9) as video:
        video.write(np.zeros((9, 15, 3), np.uint8))
        video.write(np.zeros((10, 16, 3), np.uint8))  # the padded size is accepted too
        with pytest.raises(ValueError, match="frame of size 50x40 written to a 15x9 video"):
            video.write(np.zeros((40, 50, 3), np.uint8))


def test_colours_are_bgr_and_frames_are_timed_at_the_frame_rate(tmp_path):
    path = tmp_path / "c.mp4"
    blue_bgr = np.zeros((32, 32, 3), np.uint8)
    blue_bgr[..., 0] = 200
    with VideoWriter(path, width=32, height=32, fps=4, crf=0) as video:
        for _ in range(3):
            video.write(blue_bgr)
    with av.open(str(path)) as container:
        frames = list(container.decode(video=0))
    assert [round(float(f.time), 6) for f in frames] == [0.0, 0.25, 0.5]
    pixel = frames[0].to_ndarray(format="bgr24")[16, 16].astype(int)
    assert pixel[0] > 150 and pixel[2] < 60  # blue stays blue (not swapped to red)


def test_crf_and_preset_reach_the_encoder(tmp_path):
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (64, 64, 3), dtype=np.uint8) for _ in range(4)]
    sizes = {}
    for crf, preset in ((0, "medium"), (51, "medium"), (30, "ultrafast"), (30, "veryslow")):
        path = tmp_path / f"{crf}-{preset}.mp4"
        with VideoWriter(path, width=64, height=64, crf=crf, preset=preset) as video:
            for frame in frames:
                video.write(frame)
        sizes[crf, preset] = path.stat().st_size
    assert sizes[0, "medium"] > 5 * sizes[51, "medium"]
    assert sizes[30, "ultrafast"] != sizes[30, "veryslow"]


def test_abort_then_close_leaves_nothing_and_close_twice_is_harmless(tmp_path):
    video = VideoWriter(tmp_path / "a.mp4", width=16, height=16)
    video.write(np.zeros((16, 16, 3), np.uint8))
    video.abort()
    video.close()
    assert list(tmp_path.iterdir()) == []
    with VideoWriter(tmp_path / "b.mp4", width=16, height=16) as video:
        video.write(np.zeros((16, 16, 3), np.uint8))
    video.close()
    assert [p.name for p in tmp_path.iterdir()] == ["b.mp4"]


def test_the_macroblock_tree_is_off_as_x264_records_it(tmp_path):
    """Videos are encoded with `mbtree=0` (with the tree on, long-lived workers gave different bytes for the same
    pictures, and the engines must agree byte for byte). x264 writes its settings into the stream: check them."""
    path = tmp_path / "v.mp4"
    with VideoWriter(path, width=64, height=64) as video:
        for value in (0, 128, 255):
            video.write(np.full((64, 64, 3), value, np.uint8))
    settings = path.read_bytes().split(b"options: ", 1)[1].split(b"\x00", 1)[0].decode("ascii", "replace")
    assert " mbtree=0 " in f" {settings} " and " crf=23.0 " in f" {settings} "
