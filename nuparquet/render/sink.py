"""Where output pictures go: an H.264 MP4 (opened at the first picture) and/or a folder of numbered images."""

from __future__ import annotations

from concurrent.futures import Executor, Future
from pathlib import Path

import numpy as np

from nuparquet.render.decode import write_image
from nuparquet.render.video import VideoWriter


class FrameSink:
    """Writes pictures of one size to `video` (MP4) and/or `frames_dir` (DIR/00000.<frame_format>, ...).

    Image files are written on `executor` (OpenCV encodes without the GIL); a picture handed over must not be
    modified afterwards. `close()` finishes everything; `abort()` deletes a partial video.
    """

    def __init__(self, executor: Executor, *, size: tuple[int, int], fps: float, video: Path | None = None,
                 crf: int = 23, preset: str = "veryfast", frames_dir: Path | None = None,
                 frame_format: str = "jpg"):
        self.executor = executor
        self.size = size
        self.fps = fps
        self.video, self.crf, self.preset = video, crf, preset
        self.frames_dir, self.frame_format = frames_dir, frame_format
        if frames_dir is not None:
            frames_dir.mkdir(parents=True, exist_ok=True)
        self.written = 0
        self._writer: VideoWriter | None = None
        self._image_writes: list[Future] = []

    def write(self, picture_bgr: np.ndarray) -> None:
        if self.video is not None:
            if self._writer is None:
                self._writer = VideoWriter(self.video, width=self.size[0], height=self.size[1], fps=self.fps,
                                           crf=self.crf, preset=self.preset)
            self._writer.write(picture_bgr)
        if self.frames_dir is not None:
            target = self.frames_dir / f"{self.written:05d}.{self.frame_format}"
            self._image_writes.append(self.executor.submit(write_image, target, picture_bgr))
        self.written += 1

    def close(self) -> None:
        """Wait for the image files (raising the first error) and finish the video."""
        for future in self._image_writes:
            future.result()
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def abort(self) -> None:
        """An error stopped the render: do not leave a truncated MP4 behind."""
        if self._writer is not None:
            self._writer.abort()
            self._writer = None
