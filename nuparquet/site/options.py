"""What `nuparquet report` can be asked to do: its options, their defaults and their help, declared once (each field
is a keyword of `ReportOptions` and a flag of the command). Light: no polars query, no renderer at import."""

from __future__ import annotations

from dataclasses import dataclass

from nuparquet.errors import UsageError
from nuparquet.options import option


@dataclass
class ReportOptions:
    """What each scene page holds (which scenes: a `SceneSelection`; where: the verb's `out`)."""

    overwrite: bool = option(False, help="replace DIR if it exists (only once the new report is complete)")
    videos: bool = option(
        True, help="render each scene's video (every camera tiled, with the bird's-eye view; H.264) and keyframe "
        "stills; --no-videos for a quick report without the sensor files")
    video_scale: float = option(0.25, metavar="S", help="video size relative to the camera images (default 0.25)")
    stills: int = option(4, metavar="N", help="keyframe renderings per scene page (default 4, evenly spaced)")
    max_rows: int = option(200, cli=False, help="rows shown per statistics table (the rest counted)")

    def __post_init__(self) -> None:
        if not 0 < self.video_scale <= 1:
            raise UsageError(f"--video-scale must be in (0, 1], got {self.video_scale}")
        if not 0 <= self.stills <= 20:
            raise UsageError(f"--stills must be in 0..20, got {self.stills}")
