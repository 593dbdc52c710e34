"""What `nuparquet render` can be asked to do: its options and their defaults.

Light on purpose (no cv2, no av): the CLI builds its parser from these without loading the renderer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.render.mosaic import MOSAIC_CHANNELS

CAMERA_CHANNELS = MOSAIC_CHANNELS
ALL_CHANNELS = "all"
LIDAR_CHANNEL = "LIDAR_TOP"
LABEL_MODES = ("category", "track", "none")
FRAME_FORMATS = ("jpg", "png")
ON_MISSING = ("skip", "error")
KEYFRAME_FPS = 2.0  # nuScenes keyframes are 2 Hz
ALL_FRAMES_FPS = 12.0  # cameras run at ~12 Hz
DEFAULT_CRF = 23  # x264 quality: visually clean at a modest size
DEFAULT_PRESET = "veryfast"  # encoding speed vs size; faster presets leave the 2 cores to decoding


@dataclass
class RenderOptions:
    """What to render and how; the CLI flags of `nuparquet render` one to one.

    scene: scene name. channel: a camera channel or "all" (the six cameras tiled).
    out: MP4 path; frames_dir: folder for one image per output frame (at least one of the two).
    all_frames: every camera frame (~12 Hz, boxes interpolated) instead of keyframes only.
    fps: playback rate; default 2 for keyframes, 12 with all_frames. With channel "all" and all_frames it is
        also the devkit `render_scene` sampling rate of the mosaic.
    scale: output size relative to the 1600x900 camera images. crf: x264 quality (0..51, lower is better).
    lidar: project the keyframe LIDAR_TOP points into keyframe images, coloured by depth.
    labels: "category", "track" (short instance token) or "none". clip: clip box edges at the near plane
        instead of dropping boxes partly behind the camera (the devkit drops them).
    frame_format: "jpg" or "png" for frames_dir. on_missing: "skip" (warn) or "error" (raise InputError).
    dataroot: where the images are; default the dataroot recorded in the manifest.
    progress: a tqdm bar on stderr.
    """

    scene: str
    channel: str = "CAM_FRONT"
    out: str | Path | None = None
    frames_dir: str | Path | None = None
    all_frames: bool = False
    fps: float | None = None
    scale: float = 0.5
    crf: int = DEFAULT_CRF
    lidar: bool = False
    labels: Literal["category", "track", "none"] = "category"
    clip: bool = False
    frame_format: Literal["jpg", "png"] = "jpg"
    on_missing: Literal["skip", "error"] = "skip"
    dataroot: str | Path | None = None
    progress: bool = False
    preset: str = DEFAULT_PRESET
    threads: int = 2  # decode threads

    @property
    def mosaic(self) -> bool:
        return self.channel == ALL_CHANNELS

    @property
    def frame_rate(self) -> float:
        if self.fps is not None:
            return float(self.fps)
        return ALL_FRAMES_FPS if self.all_frames else KEYFRAME_FPS

    def check(self) -> None:
        """Raise UsageError for contradictory or out-of-range options."""
        if self.out is None and self.frames_dir is None:
            raise UsageError("nothing to write: give --out FILE.mp4, --frames-dir DIR, or both")
        if not (0 < self.scale <= 4):
            raise UsageError(f"--scale must be in (0, 4], got {self.scale}")
        if self.fps is not None and not self.fps > 0:
            raise UsageError(f"--fps must be positive, got {self.fps}")
        if not 0 <= self.crf <= 51:
            raise UsageError(f"--crf must be in 0..51, got {self.crf}")
        for name, value, valid in (
            ("--labels", self.labels, LABEL_MODES),
            ("--frame-format", self.frame_format, FRAME_FORMATS),
            ("--on-missing", self.on_missing, ON_MISSING),
        ):
            if value not in valid:
                raise UsageError(f"{name} must be one of {', '.join(valid)}, got {value!r}")
