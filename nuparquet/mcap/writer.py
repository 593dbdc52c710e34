"""An MCAP file written atomically with the official `mcap` writer: chunked and compressed, every index and CRC
(chunk, data section, summary) written, schemas and channels registered once per topic.

The file is written to this process's hidden partial beside the target (`nuparquet.atomic`) and renamed into
place by `commit()`; `abort()` (or an exception inside the `with` block) deletes it, so a failed or killed export
never leaves a complete-looking file. Nothing in the file depends on when or where it was written (no clock, no
host), so the same scene gives the same bytes on every engine.
"""

from __future__ import annotations

import json
from pathlib import Path

from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from nuparquet.version import __version__
from nuparquet.atomic import move_into_place, partial_path, remove_stale

_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
LIBRARY = f"nuparquet {__version__}"


class McapFile:
    """One MCAP file being written to `path`. Use as a context manager; call `commit()` to keep it."""

    def __init__(self, path: Path | str, *, compression: str = "zstd", chunk_bytes: int = 4 * 1024 * 1024):
        self.path = Path(path)
        self.compression = compression
        self.chunk_bytes = chunk_bytes
        self.partial: Path | None = None
        self._stream = None
        self._writer: Writer | None = None
        self._schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}  # topic -> channel id

    def __enter__(self) -> McapFile:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale(self.path)  # left by a killed export (a live export's partial stays)
        self.partial = partial_path(self.path)
        self._stream = open(self.partial, "wb")  # noqa: SIM115 - closed by commit/abort
        self._writer = Writer(self._stream, chunk_size=self.chunk_bytes, compression=_COMPRESSION[self.compression],
                              enable_crcs=True, enable_data_crcs=True)
        self._writer.start(profile="", library=LIBRARY)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._stream is not None:
            self.abort()

    def protobuf_channel(self, topic: str, message_class) -> int:
        """Register `topic` carrying protobuf messages of `message_class` (its schema: the FileDescriptorSet of
        the class's file and every file it imports, as Foxglove and mcap's protobuf decoder read it)."""
        name = message_class.DESCRIPTOR.full_name
        if name not in self._schemas:
            self._schemas[name] = self._writer.register_schema(
                name=name, encoding="protobuf", data=build_file_descriptor_set(message_class).SerializeToString())
        return self._channel(topic, self._schemas[name], "protobuf")

    def json_channel(self, topic: str, schema_name: str, json_schema: dict) -> int:
        """Register `topic` carrying JSON messages described by `json_schema` (a JSON Schema object)."""
        key = f"json:{schema_name}"
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(
                name=schema_name, encoding="jsonschema", data=json.dumps(json_schema, sort_keys=True).encode())
        return self._channel(topic, self._schemas[key], "json")

    def _channel(self, topic: str, schema_id: int, encoding: str) -> int:
        if topic in self.channels:
            raise ValueError(f"topic {topic} registered twice")
        self.channels[topic] = self._writer.register_channel(topic=topic, message_encoding=encoding,
                                                             schema_id=schema_id)
        return self.channels[topic]

    def write(self, channel_id: int, time_us: int, data: bytes, sequence: int) -> None:
        """One message; log and publish time are the data's time (microseconds, written as nanoseconds)."""
        time_ns = int(time_us) * 1000
        self._writer.add_message(channel_id=channel_id, log_time=time_ns, publish_time=time_ns, data=data,
                                 sequence=sequence)

    def metadata(self, name: str, values: dict[str, str]) -> None:
        self._writer.add_metadata(name, {k: str(v) for k, v in values.items()})

    def commit(self) -> int:
        """Write the summary (schemas, channels, statistics, chunk indexes, summary offsets, CRCs), close and
        rename into place; returns the file's size in bytes."""
        self._writer.finish()
        self._stream.close()
        self._stream = None
        move_into_place(self.partial, self.path)
        return self.path.stat().st_size

    def abort(self) -> None:
        """Close without finishing and delete the partial file."""
        if self._stream is not None:
            self._stream.close()
            self._stream = None
        if self.partial is not None:
            self.partial.unlink(missing_ok=True)
