"""Where output pictures go: an H.264 MP4 (opened at the first picture) and/or a folder of numbered images, with
the frame index (`frame_index`) beside the video and in the folder."""

from __future__ import annotations

import shutil

from concurrent.futures import Executor, Future
from pathlib import Path

import numpy as np

from nuparquet.atomic import move_into_place, partial_path, remove_stale
from nuparquet.rendering.decode import write_image
from nuparquet.rendering.video.frame_index import INDEX_NAME, index_for_video, write_index
from nuparquet.rendering.video.options import existing_frames
from nuparquet.rendering.video.video import VideoWriter


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
        self._frames_partial = None
        if frames_dir is not None:  # written into a hidden sibling, moved into place by close()
            frames_dir.parent.mkdir(parents=True, exist_ok=True)
            remove_stale(frames_dir)
            self._frames_partial = partial_path(frames_dir)
            self._frames_partial.mkdir()
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
            target = self._frames_partial / f"{self.written:05d}.{self.frame_format}"
            self._image_writes.append(self.executor.submit(write_image, target, picture_bgr))
        self.written += 1

    def close(self, index: list[dict] | None = None) -> None:
        """Wait for the image files (raising the first error), finish the video, and write the frame index
        (`frame_index`) beside the video and into the frames folder."""
        for future in self._image_writes:
            future.result()
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if index is not None:
            if self.video is not None:
                write_index(index, index_for_video(self.video))
            if self._frames_partial is not None:
                write_index(index, self._frames_partial / INDEX_NAME)
        if self._frames_partial is not None:
            self._frames_partial, partial = None, self._frames_partial
            if not self.frames_dir.exists():
                move_into_place(partial, self.frames_dir)
                return
            for old in existing_frames(self.frames_dir):  # --overwrite was given (options.check refuses otherwise)
                old.unlink()
            (self.frames_dir / INDEX_NAME).unlink(missing_ok=True)
            for new in sorted(partial.iterdir()):
                move_into_place(new, self.frames_dir / new.name)
            partial.rmdir()

    def abort(self) -> None:
        """An error stopped the render: do not leave a truncated MP4 behind."""
        if self._writer is not None:
            self._writer.abort()
            self._writer = None
        for future in self._image_writes:
            future.cancel()
        if self._frames_partial is not None:
            shutil.rmtree(self._frames_partial, ignore_errors=True)
            self._frames_partial = None
