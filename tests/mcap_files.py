"""Reading MCAP files back in tests, with the `mcap` library's own readers only: every message decoded (protobuf by
the schema stored in the file, through mcap-protobuf-support's decoder; JSON by `json`), and the file checked the
way the reader checks one (summary, chunk indexes, every CRC)."""

from __future__ import annotations

import json
import struct
import zlib
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap.decoder import DecoderFactory
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import ChunkIndex, DataEnd, Footer, MessageIndex
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # opcode, record length, summary_start, summary_offset_start, summary_crc
MAGIC_BYTES = 8


class JsonDecoderFactory(DecoderFactory):
    def decoder_for(self, message_encoding, schema):
        return json.loads if message_encoding == "json" else None


@dataclass(frozen=True)
class Decoded:
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    schema_name: str
    data: bytes
    message: Any


def read_messages(path: Path) -> dict[str, list[Decoded]]:
    """topic -> its messages in file order, each decoded (the seeking reader: through the chunk indexes)."""
    out: dict[str, list[Decoded]] = defaultdict(list)
    with open(path, "rb") as f:
        decoders = [ProtobufDecoderFactory(), JsonDecoderFactory()]
        reader = SeekingReader(f, validate_crcs=True, decoder_factories=decoders)
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            out[channel.topic].append(Decoded(message.log_time, message.publish_time, message.sequence,
                                              schema.name if schema else "", message.data, decoded))
    return dict(out)


def log_times(path: Path) -> list[int]:
    """Every message's log time in file order (the non-seeking reader: record by record, CRCs checked)."""
    with open(path, "rb") as f:
        return [message.log_time for _, _, message in NonSeekingReader(f, validate_crcs=True).iter_messages()]


def validate(path: Path) -> dict:
    """Check the file as the MCAP reader can: the record stream with the data-section and chunk CRCs (StreamReader
    validate_crcs), the summary's statistics against the messages really there, every chunk index pointing at a
    chunk whose messages it lists, the summary CRC in the footer. Returns facts for further asserts."""
    data = Path(path).read_bytes()
    with open(path, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)  # raises on a bad chunk or data-section CRC
    data_end = next(r for r in records if isinstance(r, DataEnd))
    assert data_end.data_section_crc != 0, "the data section CRC was not written"
    footer = records[-1]
    assert isinstance(footer, Footer) and footer.summary_start > 0 and footer.summary_offset_start > 0
    footer_start = len(data) - MAGIC_BYTES - FOOTER_BYTES
    crc_end = footer_start + FOOTER_BYTES - 4
    (summary_crc,) = struct.unpack("<I", data[crc_end:crc_end + 4])
    assert summary_crc != 0 and summary_crc == zlib.crc32(data[footer.summary_start:crc_end]), "summary CRC"

    with open(path, "rb") as f:
        reader = SeekingReader(f, validate_crcs=True)
        summary = reader.get_summary()
        counted: dict[int, int] = defaultdict(int)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            counted[channel.id] += 1
    assert summary is not None and summary.statistics is not None
    assert dict(summary.statistics.channel_message_counts) == dict(counted)
    assert summary.statistics.message_count == sum(counted.values())
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 0

    with open(path, "rb") as f:
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if type(r).__name__ == "Chunk"]
    assert len(chunks) == len(summary.chunk_indexes)
    indexes = [r for r in records if isinstance(r, MessageIndex)]
    for index in summary.chunk_indexes:
        assert isinstance(index, ChunkIndex)
        head = data[index.chunk_start_offset:index.chunk_start_offset + 1]
        assert head == b"\x06", f"chunk index points at opcode {head!r}, not a chunk"
        assert set(index.message_index_offsets) <= set(counted)
    listed = sum(len(index.records) for index in indexes)
    assert listed == sum(counted.values()), "message indexes list every message once"
    return {"summary": summary, "chunks": chunks, "compression": {c.compression for c in chunks}}


def point_fields(cloud) -> np.ndarray:
    """The structured array a decoded foxglove.PointCloud holds (its fields at their offsets and types)."""
    types = {1: "u1", 2: "i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4", 7: "<f4", 8: "<f8"}
    dtype = np.dtype({"names": [f.name for f in cloud.fields], "formats": [types[f.type] for f in cloud.fields],
                      "offsets": [f.offset for f in cloud.fields], "itemsize": cloud.point_stride})
    return np.frombuffer(cloud.data, dtype=dtype)


def stamp_us(timestamp) -> int:
    """A google.protobuf.Timestamp as integer microseconds (exact: nanos are whole microseconds)."""
    assert timestamp.nanos % 1000 == 0
    return timestamp.seconds * 1_000_000 + timestamp.nanos // 1000
