"""`NuScenesCanBus`: the devkit's CAN bus API (`nuscenes.can_bus.can_bus_api`), served from a nuparquet output.

```python
from nuparquet.devkit.can_bus.can_bus_api import NuScenesCanBus  # instead of: from nuscenes.can_bus.can_bus_api ...
nusc_can = NuScenesCanBus(dataroot="/data/nuscenes", parquet="/data/nusc.parquet")
```

`get_messages` returns what the devkit's `json.load` of `can_bus/<scene>_<message>.json` gave (lists of dicts in file
order, the same Python types and key order; `meta` with its keys lower-cased), rebuilt from the converted
`can_bus/<message>/`, `can_bus/meta/` and `can_bus/route/` (`nuparquet.can_bus.files`): the JSON files may be gone.
Every call builds new objects, as the devkit's fresh `json.load` does, so callers may change them.

The rest is the devkit's code over that `get_messages`, statement for statement, so its checks, warnings, errors,
printed text, numbers and figures are the devkit's: the scene-name and message-name assertions, the exception for
the scenes without CAN bus data (`can_blacklist`), the warnings for misaligned routes and scene-0419, the
matplotlib figures of `plot_message_data` / `plot_baseline_route` (written to `out_path`; headless backends need no
display). Two differences, both because the output holds the converted scenes only: a file that was not converted
raises `FileNotFoundError` saying so, and `list_misaligned_routes` walks the converted files (the devkit walks every
file of the `can_bus/` folder, and fails on any that is not a scene's, such as a README).
"""

from __future__ import annotations

import errno
import json
import os
import re
import warnings

import numpy as np

from nuparquet.can_bus.blacklists import CAN_BLACKLIST, ROUTE_BLACKLIST
from nuparquet.can_bus.files import CanBusFiles
from nuparquet.can_bus.routes import nearest_route_distance_m
from nuparquet.devkit.output import open_output
from nuparquet.errors import UsageError


class NuScenesCanBus:
    """The devkit's `NuScenesCanBus` over a converted nuparquet directory.

    Args:
        dataroot: where the devkit would find the `can_bus` folder (`can_dir` is `dataroot/can_bus`, named in
            errors). Default: the dataroot the output was converted from, or, without `parquet`, the converted
            directory given here.
        max_misalignment: metres a pose may stray from the baseline route; other than 5.0 the route blacklist is
            `list_misaligned_routes(max_misalignment)` of the data. (The devkit means the same but raises
            AttributeError: it walks the routes before defining its message names, and would ask at 5 m.)
        parquet: the output directory of `nuparquet convert`; may be omitted when `dataroot` is one.
    """

    def __init__(self, dataroot: str | os.PathLike | None = None, max_misalignment: float = 5.0, *,
                 parquet: str | os.PathLike | None = None, storage_options: dict | None = None):
        dataset, dataroot = open_output(dataroot, parquet, what="nuparquet.devkit.can_bus.can_bus_api.NuScenesCanBus",
                                        convert="nuparquet convert {dataroot} --version VERSION --out OUT",
                                        storage_options=storage_options)
        self.parquet = dataset.root
        self._files = CanBusFiles(dataset)
        if not any(name.startswith("can_bus/") for name in dataset.datasets):
            reason = dataset.manifest.get("skipped", {}).get("can_bus", "not converted")
            raise UsageError(f"{dataset.root} holds no CAN bus datasets (can_bus: {reason}): convert a dataroot "
                             "whose can_bus/ folder holds the CAN bus expansion")
        self.can_dir = os.path.join(dataroot if dataroot is not None else (dataset.dataroot or str(dataset.root)),
                                    "can_bus")

        # Define all messages.
        self.can_messages = ["ms_imu", "pose", "steeranglefeedback", "vehicle_monitor", "zoesensors", "zoe_veh_info"]
        self.derived_messages = ["meta", "route"]
        self.all_messages = self.can_messages + self.derived_messages

        # Define blacklist for scenes without CAN bus data.
        self.can_blacklist = sorted(CAN_BLACKLIST)

        # Define blacklist for scenes where route and ego pose are not aligned.
        if max_misalignment == 5.0:
            self.route_blacklist = sorted(ROUTE_BLACKLIST)
        else:
            misaligned = self.list_misaligned_routes(max_misalignment)
            self.route_blacklist = [int(s[-4:]) for s in misaligned]

    def __repr__(self) -> str:
        return f"<nuparquet.devkit NuScenesCanBus can_dir={self.can_dir!r} parquet={str(self.parquet)!r}>"

    def print_all_message_stats(self, scene_name: str, print_full: bool = False) -> None:
        """Prints the meta stats for each CAN message type of a scene (the devkit's: the whole meta object under
        each message name)."""
        all_messages = {}
        for message_name in self.can_messages:
            messages = self.get_messages(scene_name, "meta")
            all_messages[message_name] = messages

        if print_full:
            print(json.dumps(all_messages, indent=2))
        else:
            partial_messages = {message: list(stats.keys()) for message, stats in all_messages.items()}
            print(json.dumps(partial_messages, indent=2))

    def print_message_stats(self, scene_name: str, message_name: str) -> None:
        """Prints the meta stats of one message type of a scene."""
        assert message_name != "meta", "Error: Cannot print stats for meta "
        messages = self.get_messages(scene_name, "meta")
        print(json.dumps(messages[message_name], indent=2))

    def plot_baseline_route(self, scene_name: str, out_path: str | None = None) -> None:
        """The baseline route and the ego poses of a scene, in a new pyplot figure (not closed: the caller closes
        it), written to `out_path` when given."""
        import matplotlib.pyplot as plt

        route, pose = self.get_pose_and_route(scene_name)

        plt.figure()
        plt.plot(route[:, 0], route[:, 1])
        plt.plot(pose[:, 0], pose[:, 1])
        plt.plot(pose[0, 0], pose[0, 1], "rx", markersize=10)
        plt.legend(("Route", "Pose", "Start"))
        plt.xlabel("Map coordinate x in m")
        plt.ylabel("Map coordinate y in m")
        if out_path is not None:
            plt.savefig(out_path)
        plt.show()

    def plot_message_data(self, scene_name: str, message_name: str, key_name: str, dimension: int = 0,
                          out_path: str | None = None, plot_format: str = "b-") -> None:
        """One field of a message type over the scene's time (`dimension` of a vector field, -1 its norm), in a new
        pyplot figure (not closed), written to `out_path` when given."""
        import matplotlib.pyplot as plt

        messages = self.get_messages(scene_name, message_name)
        data = np.array([m[key_name] for m in messages])
        utimes = np.array([m["utime"] for m in messages])

        # Convert utimes to seconds and subtract the minimum.
        utimes = (utimes - min(utimes)) / 1e6

        # Take selected column.
        if dimension == -1:
            data = np.linalg.norm(data, axis=1)
        elif dimension == 0:
            pass
        elif data.ndim > 1 and data.shape[1] >= dimension + 1:
            data = data[:, dimension]
        else:
            raise Exception('Error: Invalid dimension %d for key "%s"!' % (dimension, key_name))

        plt.figure()
        plt.plot(utimes, data, plot_format, markersize=1)
        plt.title(scene_name)
        plt.xlabel("Scene time in s")
        plt.ylabel("%s - %s" % (message_name, key_name))
        if out_path is not None:
            plt.savefig(out_path)
        plt.show()

    def list_misaligned_routes(self, max_misalignment: float = 5.0) -> list[str]:
        """The scenes whose poses stray more than `max_misalignment` m from the baseline route (the directed
        Hausdorff distance), among the converted scenes' files, as the devkit names them (`numpy.str_`)."""
        all_files = self._files.entries
        scene_list = list(np.unique([f[:10] for f in all_files]))  # the scene name of e.g. scene-0123_meta.json

        misaligned = []
        for scene_name in scene_list:
            route, pose = self._route_and_pose_xy(scene_name)
            max_dist = np.max(_nearest_distances(pose, route))
            if max_dist > max_misalignment:
                misaligned.append(scene_name)
        return misaligned

    def get_pose_and_route(self, scene_name: str, print_warnings: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(route, pose): the baseline route's points and the poses' x, y as numpy arrays."""
        route = self.get_messages(scene_name, "route", print_warnings=print_warnings)
        pose = self.get_messages(scene_name, "pose", print_warnings=print_warnings)

        route = np.asarray(route)
        pose = np.asarray([p["pos"][:2] for p in pose])
        return route, pose

    def _route_and_pose_xy(self, scene_name: str) -> tuple[np.ndarray, np.ndarray]:
        """`get_pose_and_route(scene_name, print_warnings=False)` for the distances only: after the same checks,
        the route's x, y and the poses' `pos` read as numbers, no message built (an empty file as the devkit's
        `np.asarray([])`). Poses whose `pos` is not a fixed-size list of numbers take the devkit's way."""
        from nuparquet.columns import to_numpy

        route_file = self._file_name(scene_name, "route", False)
        pose_file = self._file_name(scene_name, "pose", False)
        poses = self._files.table(pose_file, ["pos"])
        kind = poses.schema.field("pos").type if "pos" in poses.column_names else None
        if kind is None or not (_fixed_numbers(kind) and poses.column("pos").null_count == 0):
            return self.get_pose_and_route(scene_name, print_warnings=False)
        route = self._files.table(route_file, ["x", "y"])
        route_xy = np.column_stack([route.column("x").to_numpy(), route.column("y").to_numpy()])
        pose_xy = to_numpy(poses.column("pos"), (kind.list_size,))[:, :2]
        return (route_xy if len(route_xy) else np.asarray([])), (pose_xy if len(pose_xy) else np.asarray([]))

    def _file_name(self, scene_name: str, message_name: str, print_warnings: bool) -> str:
        """The converted file `get_messages` reads, after its checks and warnings (the devkit's, in its order)."""
        # Check inputs. Scene names must be in the format scene-0123.
        assert re.match("^scene-\\d\\d\\d\\d$", scene_name)
        assert message_name in self.all_messages, "Error: Invalid CAN bus message name: %s" % message_name

        # Check for data issues.
        scene_id = int(scene_name[-4:])
        if scene_id in self.can_blacklist:
            # Check for logs that have no CAN bus data.
            raise Exception("Error: %s does not have any CAN bus data!" % scene_name)
        elif print_warnings:
            # Print warnings for scenes that are known to have bad data.
            if message_name == "route":
                if scene_id in self.route_blacklist:
                    warnings.warn("Warning: %s is not well aligned with the baseline route!" % scene_name)
            elif message_name == "vehicle_monitor":
                if scene_id in [419]:
                    warnings.warn("Warning: %s does not have any vehicle_monitor messages!")  # sic: the devkit's

        name = "%s_%s.json" % (scene_name, message_name)
        if name not in self._files.entries:
            raise FileNotFoundError(errno.ENOENT, f"No such file or directory (not among the CAN bus files "
                                                  f"converted into {self.parquet})", os.path.join(self.can_dir, name))
        return name

    def get_messages(self, scene_name: str, message_name: str, print_warnings: bool = True) -> list[dict] | dict:
        """The messages of a scene and message type as the devkit's `json.load` gave them: a list of messages, or
        for `meta` a dict with lower-cased keys. Asserts a `scene-0123` name and a known message name; raises for
        the scenes without CAN bus data and warns for those with known problems, as the devkit does.

        Raises:
            FileNotFoundError: the file was not converted (the devkit's error when it is absent).
        """
        name = self._file_name(scene_name, message_name, print_warnings)
        messages = self._files.content(name)
        assert type(messages) in [list, dict]

        # Rename all dict keys to lower-case.
        if isinstance(messages, dict):
            messages = {k.lower(): v for (k, v) in messages.items()}
        return messages


def _fixed_numbers(kind) -> bool:
    """A fixed-size list of integers or floats (Arrow type)."""
    import pyarrow as pa

    return pa.types.is_fixed_size_list(kind) and (pa.types.is_integer(kind.value_type)
                                                  or pa.types.is_floating(kind.value_type))


def _nearest_distances(pose: np.ndarray, route: np.ndarray) -> np.ndarray:
    """`scipy.spatial.distance.cdist(pose, route).min(axis=1)`, with cdist's refusals of arrays it cannot take."""
    if pose.ndim != 2:
        raise ValueError("XA must be a 2-dimensional array.")
    if route.ndim != 2:
        raise ValueError("XB must be a 2-dimensional array.")
    if pose.shape[1] != route.shape[1]:
        raise ValueError("XA and XB must have the same number of columns (i.e. feature dimension.)")
    if len(route) == 0 and len(pose):
        raise ValueError("zero-size array to reduction operation minimum which has no identity")
    return nearest_route_distance_m(pose.astype(np.float64), route.astype(np.float64))
