"""What `nuparquet synth` (and `nuparquet.synthesize`) can be asked to write: one dataclass whose fields are both
the keywords of `synthesize` and the flags of the CLI. Light on purpose (no OpenCV): the CLI builds its parser
from it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nuparquet.errors import UsageError
from nuparquet.options import option

PROFILES = ("regular", "irregular")  # `irregular`: the cases regular data lacks
FAMILIES = ("nuscenes", "nuimages", "truckscenes")


@dataclass
class SynthOptions:
    scenes: int = option(help="number of scenes (850 is nuScenes trainval scale)", metavar="N")
    samples_per_scene: int = option(40, metavar="K",
                                    help="keyframes per scene at 2 Hz (default 40: 20 s scenes like nuScenes)")
    with_images: bool = option(
        False, help="write the camera JPEGs of all keyframes and sweeps (slow: ~36 JPEGs per sample)")
    with_lidar: bool = option(
        False, help="write the lidar .pcd.bin and radar .pcd files of all keyframes and sweeps, and lidarseg/panoptic "
        "labels of the lidar keyframes")
    with_can_bus: bool = option(
        True, flag="--can-bus", help="write the CAN bus expansion (can_bus/: every scene's files but the last's); "
        "--no-can-bus leaves it out")
    wild_can_bus: bool = option(
        False, help="write the CAN bus files in the shapes real ones take beyond the regular: streams starting after "
        "the first keyframes, dropped messages and 1 s gaps, a zoesensors stream, mixed-case meta keys, var_stats "
        "objects (for tests)")
    seed: int = option(0, help="random seed (default 0); same seed, same dataset")
    version: str = option("v1.0-synth", help="version folder name (default v1.0-synth)")
    rig: Literal["nuscenes", "lyft"] = option(  # the names of `taxonomy.RIGS`
        "nuscenes", help="the sensor set: nuscenes (6 cameras, LIDAR_TOP, 5 radars; default) or lyft (7 cameras with "
        "a zoomed front camera, 3 lidars, no radar)")
    family: Literal["nuscenes", "nuimages", "truckscenes"] = option(
        "nuscenes", flag="--format", help="the dataset family written: nuscenes (default; --rig picks the sensor "
        "set), nuimages (the ten nuImages tables that nuimages.NuImages loads, with JPEGs and RLE masks: --scenes "
        "logs of --samples-per-scene annotated keyframes, each with 6 images before and 6 after) or truckscenes "
        "(the fourteen MAN TruckScenes tables that truckscenes.TruckScenes loads, with JPEGs of its 4 cameras and "
        ".pcd files of its 6 lidars and 6 radars)")
    profile: Literal["regular", "irregular"] = option(
        "regular", help="regular (default), or irregular: the cases regular data lacks, for tests (tracks with 1-3 s "
        "gaps, hills, boxes and lidar points just in front of CAM_FRONT, frames on the 10 Hz clock, a late first "
        "CAM_FRONT frame, and a VERSION-test folder with empty annotation tables)")

    def __post_init__(self) -> None:
        if isinstance(self.scenes, bool) or not isinstance(self.scenes, int) or self.scenes < 1:
            raise UsageError(f"--scenes must be a positive integer, got {self.scenes!r}")
        if isinstance(self.samples_per_scene, bool) or not isinstance(self.samples_per_scene, int) \
                or self.samples_per_scene < 1:
            raise UsageError(f"--samples-per-scene must be a positive integer, got {self.samples_per_scene!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise UsageError(f"--seed must be a non-negative integer, got {self.seed!r}")
        if not self.version or "/" in self.version or "\\" in self.version or self.version.startswith("."):
            raise UsageError(f"--version must be a plain folder name such as v1.0-synth, got {self.version!r}")
        from nuparquet.synth.taxonomy import RIGS  # dataclasses only: light

        if self.rig not in RIGS:
            raise UsageError(f"--rig must be one of {', '.join(RIGS)}, got {self.rig!r}")
        if self.family not in FAMILIES:
            raise UsageError(f"--format must be one of {', '.join(FAMILIES)}, got {self.family!r}")
        if self.profile not in PROFILES:
            raise UsageError(f"--profile must be one of {', '.join(PROFILES)}, got {self.profile!r}")
