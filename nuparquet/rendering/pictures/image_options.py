"""What `nuparquet render` draws as one picture (one sample, sample_data, annotation, instance, or a map picture) and
how: declared once, each field both a keyword of `ImageOptions` and a flag of `nuparquet render` (the flags it shares
with the scene render, `--scale`, `--labels`, `--lidar-color`, come from `RenderOptions`; `--out` and `--dataroot`
are the command's own).

Light on purpose (no cv2): the CLI builds its parser from it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.options import check_choices, option
from nuparquet.rendering.colorings import LidarColor

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
MAP_PICTURES = ("map_patch", "map_record", "map_mask", "centerlines", "ego_poses", "next_roads")


def _floats(values, count: int, flag: str) -> tuple[float, ...]:
    try:
        numbers = tuple(float(v) for v in values)
    except ValueError:
        raise UsageError(f"{flag} takes {count} comma-separated numbers, got {','.join(values)!r}") from None
    if len(numbers) != count:
        raise UsageError(f"{flag} takes {count} comma-separated numbers, got {len(numbers)}")
    return numbers


@dataclass
class ImageOptions:
    """One picture: what (`sample`, `sample_data`, `annotation`, `instance`, or `map` with one map picture) and how."""

    sample: str | None = option(
        None, metavar="TOKEN", help="draw every sensor of this sample in one picture (each lidar and the fused radars "
        "from above, every camera with its boxes); with --pointcloud-in-image or --map-in-image one camera of it")
    sample_data: str | None = option(
        None, metavar="TOKEN", help="draw this sample_data: a camera image with its boxes, or a lidar / radar frame "
        "from above (with --nsweeps, --lidar-color, the map underneath), as the devkit's render_sample_data")
    annotation: str | None = option(
        None, metavar="TOKEN", help="draw this annotation: its lidar view beside the first camera that sees it")
    instance: str | None = option(
        None, metavar="TOKEN", help="draw this instance: its annotation nearest the ego (--instance-annotation)")
    map: str | None = option(
        None, metavar="LOCATION", help="a map picture of this location: with --map-patch, --map-record, --map-mask, "
        "--centerlines, --ego-poses or --next-roads")
    map_patch: tuple[str, ...] = option(
        (), metavar="XMIN,YMIN,XMAX,YMAX", help="the map layers over this rectangle (map metres)")
    map_record: str | None = option(None, metavar="LAYER:TOKEN", help="one map record, in the whole map and close up")
    map_mask: tuple[str, ...] = option(
        (), metavar="X,Y,H,W", help="get_map_mask's masks of the patch centred at X,Y, H high and W wide (metres)")
    map_angle: float = option(0.0, metavar="DEG", help="--map-mask: the patch's orientation (degrees, 0 = north up)")
    canvas_size: tuple[str, ...] = option(("100", "100"), metavar="H,W", help="--map-mask: the masks' size in pixels")
    map_layers: tuple[str, ...] = option(
        (), metavar="A,B,...", help="the map layers to draw (default: every layer; --map-in-image: road_segment, lane, "
        "ped_crossing, walkway, stop_line, carpark_area)")
    centerlines: bool = option(False, help="with --map: every lane's centreline")
    ego_poses: bool = option(False, help="with --map: the ego poses of its scenes (or of --scenes) over the map")
    next_roads: tuple[str, ...] = option((), metavar="X,Y", help="with --map: the roads that may follow the one at X,Y")
    map_in_image: bool = option(False, help="with --sample: the map layers projected into --camera-channel's image")
    pointcloud_in_image: bool = option(
        False, help="with --sample: the --pointsensor-channel points on the --camera-channel image")
    camera_channel: str | None = option(None, metavar="CHANNEL", help="the camera (default: the default camera)")
    pointsensor_channel: str | None = option(
        None, metavar="CHANNEL", help="the lidar or radar of --pointcloud-in-image (default: the reference lidar)")
    nsweeps: int = option(1, metavar="N", help="lidar / radar views: this many sweeps aggregated (default 1)")
    box_vis_level: Literal["any", "all", "none"] = option(
        "any", help="camera boxes drawn: any corner in the image (default), all corners, or every box in front")
    axes_limit: float = option(40.0, metavar="M", help="lidar / radar views: metres from the ego to each edge")
    underlay_map: bool = option(True, help="lidar / radar views: the map underneath (--no-underlay-map: none)")
    filter_lidarseg_labels: tuple[str, ...] = option(
        (), metavar="I,J,...", help="with --lidar-color lidarseg or panoptic: only these class indices")
    lidarseg_legend: bool = option(False, help="with --lidar-color lidarseg or panoptic: a legend of the classes")
    lidarseg_preds: str | Path | None = option(
        None, metavar="FILE", help="colour by the predictions in this .bin (lidarseg) or .npz (panoptic) file, drawn "
        "beside the ground truth")
    instance_annotation: Literal["closest", "middle"] = option(
        "closest", help="--instance: the annotation nearest the ego (the devkit's choice, default) or the one in the "
        "middle of the track")
    extra_info: bool = option(False, help="--annotation, --instance: the devkit's text (category, points, distance, "
                              "size) below")
    # Shared with the scene render, whose flags (--scale, --labels, --lidar-color, --scenes) set them on the CLI:
    scale: float | None = option(None, cli=False, help="camera pictures' size relative to the images (default: "
                                 "full size, as the devkit shows them; a sample's grid of every sensor: 0.35)")
    labels: Literal["category", "track", "none"] = option("none", cli=False, help="box labels")
    lidar_color: LidarColor = option(
        "depth", cli=False, help="how lidar points are coloured")
    scenes: tuple[str, ...] = option((), cli=False, help="--ego-poses: these scenes (default: every scene there)")

    @property
    def targets(self) -> list[str]:
        """The flags naming what to draw that were given."""
        names = ("sample", "sample_data", "annotation", "instance", "map")
        return [name for name in names if getattr(self, name) is not None]

    @property
    def wanted(self) -> bool:
        """A picture was asked for: something to draw, or an option only a picture takes."""
        return bool(self.targets) or self.map_in_image or self.pointcloud_in_image or any(
            getattr(self, name) not in (None, (), False) for name in MAP_PICTURES)

    def map_picture(self) -> str:
        given = [name for name in MAP_PICTURES if getattr(self, name) not in (None, (), False)]
        if len(given) != 1:
            raise UsageError("--map LOCATION draws one map picture: give one of --map-patch, --map-record, --map-mask, "
                             "--centerlines, --ego-poses, --next-roads" + (f" (got {', '.join(given)})" if given else ""))
        return given[0]

    def check(self) -> None:
        """UsageError unless exactly one thing is asked for, with the options it takes."""
        if self.map is None and any(getattr(self, name) not in (None, (), False) for name in MAP_PICTURES):
            raise UsageError("--map-patch, --map-record, --map-mask, --centerlines, --ego-poses and --next-roads draw "
                             "a map: give --map LOCATION")
        if (self.map_in_image or self.pointcloud_in_image) and self.sample is None:
            raise UsageError("--map-in-image and --pointcloud-in-image draw one camera of a sample: give --sample TOKEN")
        if len(self.targets) != 1:
            given = ", ".join("--" + t.replace("_", "-") for t in self.targets)
            raise UsageError("draw one thing at a time: --sample, --sample-data, --annotation, --instance or --map"
                             + (f" (got {given})" if given else ""))
        if self.map is not None:
            self.map_picture()
        if self.map_in_image and self.pointcloud_in_image:
            raise UsageError("--map-in-image or --pointcloud-in-image, not both")
        if self.nsweeps < 1:
            raise UsageError(f"--nsweeps must be at least 1, got {self.nsweeps}")
        if not self.axes_limit > 0:
            raise UsageError(f"--axes-limit must be positive, got {self.axes_limit}")
        if self.scale is not None and not 0 < self.scale <= 4:
            raise UsageError(f"--scale must be in (0, 4], got {self.scale}")
        check_choices(self)

    def floats(self, name: str, count: int) -> tuple[float, ...]:
        return _floats(getattr(self, name), count, "--" + name.replace("_", "-"))

    def class_indices(self) -> list[int] | None:
        if not self.filter_lidarseg_labels:
            return None
        try:
            return [int(v) for v in self.filter_lidarseg_labels]
        except ValueError:
            raise UsageError("--filter-lidarseg-labels takes class indices (integers), e.g. 22,23") from None


def check_image_path(path) -> Path:
    """UsageError unless `path` names a PNG or JPEG file."""
    path = Path(path)
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise UsageError(f"--out {path}: a picture is written as .png or .jpg")
    if path.is_dir():
        raise UsageError(f"--out {path} is a directory; give the picture's file name")
    return path


FIELDS = tuple(f.name for f in fields(ImageOptions))
