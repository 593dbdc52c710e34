"""What the MP4s hold, decoded back with PyAV: frames in the order written, odd sizes padded by replicating
the last row/column (bottom/right), pixel values kept; and a rendered scene video whose frames are the
scene's camera images in the devkit's sample order."""

from __future__ import annotations

import av
import cv2
import numpy as np
import pytest

from nuparquet.cli.main import main
from nuparquet.render.video import VideoWriter
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
