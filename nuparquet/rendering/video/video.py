"""H.264 MP4 writing with PyAV: libx264, yuv420p, `+faststart`, even frame sizes — a file a web browser plays.

Modelled on av2-api's `rendering/video/video.py`, but streaming (one frame at a time, constant memory) instead of
taking the whole (N, H, W, 3) video as one array, and with `movflags` set on the muxer, where it takes effect.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import av
import cv2
import numpy as np

from nuparquet.atomic import move_into_place, partial_path, remove_stale
from nuparquet.rendering.video.options import DEFAULT_CRF, DEFAULT_PRESET



def even_size(width: int, height: int) -> tuple[int, int]:
    """The (width, height) a frame of this size is padded to: yuv420p needs both to be even."""
    return width + width % 2, height + height % 2


def pad_to_even(image_bgr: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 -> (H', W', 3) with H', W' even: odd sides get one replicated row/column at the end."""
    height, width = image_bgr.shape[:2]
    pad_bottom, pad_right = height % 2, width % 2
    if not (pad_bottom or pad_right):
        return image_bgr
    return cv2.copyMakeBorder(image_bgr, 0, pad_bottom, 0, pad_right, cv2.BORDER_REPLICATE)


def frame_rate(fps: float) -> Fraction:
    """`fps` as the exact rational PyAV wants (12 -> 12/1, 29.97 -> 2997/100)."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return Fraction(fps).limit_denominator(1001)


class VideoWriter:
    """Encode BGR frames of one size into an H.264 MP4, one `write` at a time.

    >>> with VideoWriter("scene.mp4", width=800, height=450, fps=2) as video:
    ...     video.write(image_bgr)          # (450, 800, 3) uint8

    The size is fixed by the constructor (odd sizes are padded by one pixel, see `even_size`); frames of
    another size are rejected. `crf` is x264's constant rate factor (0 lossless .. 51 worst, 23 default);
    `preset` trades encoding speed for file size. Frames go to a hidden temporary file beside `path`, renamed
    to `path` by `close()`: a render killed midway (even by SIGKILL) never leaves a truncated video at `path`.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        width: int,
        height: int,
        fps: float = 2.0,
        crf: int = DEFAULT_CRF,
        preset: str = DEFAULT_PRESET,
        threads: int = 0,
    ) -> None:
        if not 0 <= int(crf) <= 51:
            raise ValueError(f"crf must be in 0..51, got {crf}")
        self.path = Path(path)
        self.input_size = (int(width), int(height))
        self.width, self.height = even_size(int(width), int(height))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale(self.path)  # left by a killed render (a live render's partial stays)
        self.partial = partial_path(self.path)
        # movflags is a muxer option: on the stream (as av2 sets it) ffmpeg ignores it and moov stays at the end.
        self._container = av.open(str(self.partial), mode="w", format="mp4", options={"movflags": "+faststart"})
        stream = self._container.add_stream("libx264", rate=frame_rate(fps))
        stream.width, stream.height = self.width, self.height
        stream.pix_fmt = "yuv420p"
        # mbtree off: with it x264 read memory it had not written (seen with short videos, 3-15 frames, in
        # long-lived worker processes), and the same pixels gave different files; with it off a video is the same
        # bytes whichever process or engine renders it (`nuparquet render --all-scenes --engine ...`).
        stream.options = {"crf": str(int(crf)), "preset": preset, "threads": str(int(threads)),
                          "x264-params": "mbtree=0"}
        self._stream = stream
        self.frames_written = 0

    def write(self, image_bgr: np.ndarray) -> None:
        """Append one (height, width, 3) uint8 BGR frame."""
        if image_bgr.shape[:2] != self.input_size[::-1] and image_bgr.shape[:2] != (self.height, self.width):
            raise ValueError(
                f"frame of size {image_bgr.shape[1]}x{image_bgr.shape[0]} written to a "
                f"{self.input_size[0]}x{self.input_size[1]} video"
            )
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(pad_to_even(image_bgr)), format="bgr24")
        frame.pts = self.frames_written
        self._container.mux(self._stream.encode(frame))
        self.frames_written += 1

    def close(self) -> None:
        """Flush the encoder and finish the file (writes the index at the front: `+faststart`)."""
        if self._container is None:
            return
        try:
            self._container.mux(self._stream.encode(None))
        finally:
            self._container.close()
            self._container = None
        move_into_place(self.partial, self.path)

    def abort(self) -> None:
        """Close without flushing and delete the partial file."""
        if self._container is not None:
            try:
                self._container.close()
            except Exception:  # noqa: BLE001 - the file is being thrown away
                pass
            self._container = None
        self.partial.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
