"""One scene as one MCAP file that Foxglove opens without configuration.

```python
import nuparquet
result = nuparquet.export_mcap("OUT", "scene-0061", out="scene-0061.mcap", on_progress=print)
result.messages          # {"/tf": 3140, "/CAM_FRONT/image_rect_compressed": 240, ...}
```

The stages: one query for the scene's rows (`scene`), one `Stream` per topic (`streams`), then every message of
every stream merged into log-time order (ties: the stream order below, then row order) and written one at a time
into a chunked, compressed MCAP file (`writer`), renamed into place when complete. Sensor files are read as
their messages are written; a missing or unreadable one is skipped and named (or, with on_missing="error",
stops the export).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nuparquet.channels import default_camera
from nuparquet.dataset import as_dataset
from nuparquet.errors import InputError
from nuparquet.mcap.options import McapOptions, check_target
from nuparquet.mcap.scene import can_bus_messages, load_scene
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter


@dataclass
class McapResult:
    """What an export wrote: `messages` per topic (in file order), the file's size, the bytes of the sensor files
    it carries, and the files that were missing or unreadable (skipped)."""

    scene: str
    out: Path
    messages: dict[str, int]
    bytes: int
    sensor_bytes: int
    start_us: int
    end_us: int
    missing: list[str] = field(default_factory=list)

    @property
    def total_messages(self) -> int:
        return sum(self.messages.values())

    def summary_entry(self, file_name: str) -> dict:
        """This scene's entry in a many-scene export's summary (`mcap-summary.json`)."""
        return {"file": file_name, "bytes": self.bytes, "messages": self.messages, "sensor_bytes": self.sensor_bytes,
                "missing": len(self.missing), "first_missing": self.missing[:5]}


def build_streams(dataset, rows, options: McapOptions, dataroot: Path | None) -> list:
    """Every topic of the file, in the order messages of equal time are written: map, transforms, then per
    channel (by name) calibration, image or points, then boxes and the CAN bus."""
    from nuparquet.mcap import streams
    from nuparquet.mcap.points import PointReader

    frames = rows.frames
    out = []
    if options.wants("map") and "map/lane" in dataset.datasets and frames.height:
        from nuparquet.mcap.map_layers import map_layers_near, route_box
        from nuparquet.frames.poses import sensor_poses

        global_from_ego, _ = sensor_poses(frames)
        box = route_box(global_from_ego[:, :2, 3], options.map_margin_m)
        layers = map_layers_near(dataset, rows.scene["log_location"], box)
        if layers:
            out.append(streams.map_stream(int(frames["timestamp"].min()), layers))
    if options.wants("transforms"):
        out.append(streams.transform_stream(frames))
    reader = PointReader(dataset, rows.name)
    for (channel, modality), part in sorted(frames.partition_by("channel", "modality", as_dict=True).items()):
        if modality == "camera":
            out += streams.camera_streams(part, channel, dataset.sensors, dataroot, images=options.wants("images"))
        elif modality in ("lidar", "radar") and options.wants("points"):
            out.append(streams.point_stream(part, channel, modality, dataroot, reader))
    if options.wants("boxes"):
        facts = dataset.channels
        camera = default_camera(facts.get("cameras", []), facts.get("camera_layout"))
        out.append(streams.box_stream(rows, camera, options.boxes))
    if options.wants("can_bus"):
        for message, table in sorted(can_bus_messages(dataset, rows.name).items()):
            if table.height:
                out.append(streams.can_bus_stream(message, table))
    return out


def message_order(streams) -> tuple[np.ndarray, np.ndarray]:
    """(stream index, row) of every message in log-time order; equal times keep stream order, then row order."""
    stream = np.concatenate([np.full(len(s), k, dtype=np.int64) for k, s in enumerate(streams)] or [np.zeros(0, int)])
    row = np.concatenate([np.arange(len(s), dtype=np.int64) for s in streams] or [np.zeros(0, int)])
    times = np.concatenate([np.asarray(s.times_us, dtype=np.int64) for s in streams] or [np.zeros(0, int)])
    order = np.lexsort((row, stream, times))
    return stream[order], row[order]


def export_mcap(dataset, scene: str, out, options: McapOptions | None = None, *,
                on_progress: OnProgress | None = None, **fields) -> McapResult:
    """Write `scene` of `dataset` (a `Dataset` or a path) as the MCAP file `out`, as `options` (or keyword fields of
    `McapOptions`) say (see the module docstring and `streams` for the topics). Progress goes to `on_progress`, one
    "message" unit per message.

    Raises:
        UsageError: bad options, an unknown scene, no dataroot with the sensor files (when images or points are
            wanted).
        InputError: with on_missing="error", the first missing or unreadable sensor file (named by path).
    """
    from nuparquet.mcap.streams import MissingFile
    from nuparquet.mcap.writer import McapFile

    options = resolve(McapOptions, options, fields)
    out = check_target(out)
    dataset = as_dataset(dataset)
    if not dataset.is_remote:  # never write into the converted dataset
        from nuparquet.atomic import check_apart

        check_apart(out, dataset.root, what="the converted dataset")
    dataset.check_scenes([scene])
    rows = load_scene(dataset, scene)
    needed = [*(["camera"] if options.wants("images") else []), *(["lidar", "radar"] if options.wants("points") else [])]
    # the dataroot is needed unless the output embeds every file wanted (`convert --embed`)
    dataroot = dataset.sensors.root("the images and points", otherwise=", or --without images,points") \
        if needed and not dataset.sensors.embeds(*needed) else None
    streams = build_streams(dataset, rows, options, dataroot)
    stream_of, row_of = message_order(streams)

    counts = {s.topic: 0 for s in streams}
    missing: list[str] = []
    sensor_bytes = 0
    with Reporter(on_progress, f"export-mcap {scene}", total=len(stream_of), unit="message") as reporter, \
            McapFile(out, compression=options.compression, chunk_bytes=options.chunk_bytes) as mcap:
        scene_row = rows.scene
        mcap.metadata("scene", {"name": scene_row["name"], "description": scene_row.get("description") or "",
                                "log_location": scene_row.get("log_location") or "", "vehicle": scene_row.get("vehicle") or "",
                                "date_captured": scene_row.get("date_captured") or "",
                                "source_version": dataset.version or ""})
        channel_ids = [mcap.protobuf_channel(s.topic, s.schema) if not isinstance(s.schema, tuple)
                       else mcap.json_channel(s.topic, *s.schema) for s in streams]
        for k, i in zip(stream_of.tolist(), row_of.tolist()):
            stream = streams[k]
            try:
                data = stream.encode(i)
            except MissingFile as exc:
                if options.on_missing == "error":
                    raise InputError(f"sensor file {exc.path}: {exc.reason} (--on-missing skip leaves such "
                                     "messages out)") from None
                missing.append(exc.path)
                reporter.advance(step="missing file")
                continue
            counts[stream.topic] += 1
            mcap.write(channel_ids[k], int(stream.times_us[i]), data, sequence=counts[stream.topic])
            if stream.reads_bytes is not None:
                sensor_bytes += stream.reads_bytes(i)
            reporter.advance()
        size = mcap.commit()
    times = [int(s.times_us.min()) for s in streams if len(s)] or [0]
    ends = [int(s.times_us.max()) for s in streams if len(s)] or [0]
    return McapResult(scene=scene, out=out, messages=counts, bytes=size, sensor_bytes=sensor_bytes,
                      start_us=min(times), end_us=max(ends), missing=missing)
