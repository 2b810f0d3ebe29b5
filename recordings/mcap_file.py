"""A chunked MCAP writer for many small messages, built on the mcap library's record classes.

The mcap library's ``Writer.add_message`` costs about 5 µs of Python per message (a record object,
statistics, an index entry, seven stream calls): an in-process run produces 80 000 messages per
second, so that alone would take 40 % of the recorder's core. Here message records arrive as whole
blocks, built for a batch of messages at once (``recordings.encoding``), with their channels, log
times and offsets as arrays, and the message indexes are written from those arrays; every other
record — header, schemas, channels, metadata, attachments, chunks, the summary with its statistics
and indexes, the footer — is written with the library's record classes, and the library's readers
read the file (the tests read every recording with CRCs checked and with
``mcap.reader.make_reader``). Schemas and channels are written before the first chunk, outside
chunks, so that a file cut short still declares them. Every chunk carries the CRC-32 of its records,
the ``DataEnd`` record the CRC-32 of the whole data section and the footer the summary's: no byte of a
finished file goes unchecked (``recordings.mcap_read`` checks them all).
"""
from __future__ import annotations

import hashlib
import struct
import zlib
from collections import defaultdict
from typing import BinaryIO

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

_MESSAGE_INDEX = struct.Struct("<BQHI")  # opcode, record length, channel id, byte length of its (time, offset) pairs


class _Summed:
    """A binary stream that keeps the CRC-32 and the SHA-256 of every byte written to it."""

    def __init__(self, stream: BinaryIO) -> None:
        self.stream = stream
        self.crc = 0
        self.sha256 = hashlib.sha256()

    def write(self, data) -> None:
        self.crc = zlib.crc32(data, self.crc)
        self.sha256.update(data)
        self.stream.write(data)

    def tell(self) -> int:
        return self.stream.tell()

    def flush(self) -> None:
        self.stream.flush()


def _record(record: McapRecord) -> bytes:
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


class McapFile:
    """An MCAP file being written to ``stream``: ZSTD chunks of about ``chunk_bytes`` of messages."""

    def __init__(self, stream: BinaryIO, library: str, chunk_bytes: int) -> None:
        self._stream = _Summed(stream)
        self._chunk_bytes = chunk_bytes
        self._compress = zstandard.ZstdCompressor(level=1).compress
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk = bytearray()
        self._indexes: dict[int, list[np.ndarray]] = defaultdict(list)  # channel → (log time, offset in chunk) pairs
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = defaultdict(int)
        self._times: tuple[int, int] | None = None  # first and last log time of every message
        self._stream.write(MCAP0_MAGIC)
        self._stream.write(_record(Header(profile="", library=library)))

    def schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._stream.write(_record(schema))
        return schema.id

    def channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        channel = Channel(id=len(self._channels) + 1, topic=topic, message_encoding=message_encoding,
                          schema_id=schema_id, metadata=metadata)
        self._channels.append(channel)
        self._stream.write(_record(channel))
        return channel.id

    def metadata(self, name: str, data: dict[str, str]) -> None:
        offset = self._stream.tell()
        record = _record(Metadata(name=name, metadata=data))
        self._stream.write(record)
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(record), name=name))

    def attachment(self, name: str, media_type: str, data: bytes, time_ns: int) -> None:
        offset = self._stream.tell()
        record = _record(Attachment(create_time=time_ns, log_time=time_ns, name=name, media_type=media_type, data=data))
        self._stream.write(record)
        self._attachment_indexes.append(AttachmentIndex(offset=offset, length=len(record), log_time=time_ns,
                                                        create_time=time_ns, data_size=len(data), name=name,
                                                        media_type=media_type))

    def messages(self, records: np.ndarray, channel_ids: np.ndarray, log_times: np.ndarray,
                 offsets: np.ndarray) -> None:
        """Add message records (``recordings.encoding``) to the open chunk: ``records`` holds them one after the
        other, at ``offsets``, of ``channel_ids`` at ``log_times``; the chunk is written out once it holds
        ``chunk_bytes``."""
        if not offsets.size:
            return
        pairs = np.column_stack((log_times, offsets + len(self._chunk))).astype("<u8")
        for channel_id in np.flatnonzero(np.bincount(channel_ids)).tolist():  # a few channels: a mask each
            self._indexes[channel_id].append(pairs[channel_ids == channel_id])
        self._chunk += memoryview(records)  # a bytearray + an ndarray would be numpy's addition
        if len(self._chunk) >= self._chunk_bytes:
            self._write_chunk()

    def flush(self) -> None:
        """Write the open chunk and hand everything to the operating system."""
        self._write_chunk()
        self._stream.flush()

    def written(self) -> tuple[str, dict[int, int], int]:
        """The SHA-256 (hex) of every byte written so far, the messages written per channel id and the number of
        chunks written (the open chunk is not written yet: ``flush`` first)."""
        return self._stream.sha256.hexdigest(), dict(self._counts), len(self._chunk_indexes)

    def finish(self) -> None:
        """Write the last chunk, the summary (schemas, channels, statistics, indexes) and the footer."""
        self._write_chunk()
        self._stream.write(_record(DataEnd(data_section_crc=self._stream.crc)))
        summary_start = self._stream.tell()
        statistics = Statistics(
            message_count=sum(self._counts.values()), schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=len(self._attachment_indexes),
            metadata_count=len(self._metadata_indexes), chunk_count=len(self._chunk_indexes),
            message_start_time=self._times[0] if self._times else 0,
            message_end_time=self._times[1] if self._times else 0, channel_message_counts=dict(self._counts))
        summary = bytearray()
        offsets = []
        for opcode, records in ((Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels),
                                (Opcode.STATISTICS, [statistics]), (Opcode.CHUNK_INDEX, self._chunk_indexes),
                                (Opcode.ATTACHMENT_INDEX, self._attachment_indexes),
                                (Opcode.METADATA_INDEX, self._metadata_indexes)):
            group = b"".join(_record(r) for r in records)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + len(summary),
                                         group_length=len(group)))
            summary += group
        summary_offset_start = summary_start + len(summary)
        summary += b"".join(_record(offset) for offset in offsets)
        footer_fields = struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start)
        crc = zlib.crc32(footer_fields, zlib.crc32(summary))
        self._stream.write(summary)
        self._stream.write(_record(Footer(summary_start=summary_start, summary_offset_start=summary_offset_start,
                                          summary_crc=crc)))
        self._stream.write(MCAP0_MAGIC)
        self._stream.flush()

    def _write_chunk(self) -> None:
        if not self._chunk:
            return
        indexes = {channel_id: np.concatenate(parts) for channel_id, parts in self._indexes.items()}
        times = np.concatenate([pairs[:, 0] for pairs in indexes.values()])
        first, last = int(times.min()), int(times.max())
        self._times = (min(first, self._times[0]), max(last, self._times[1])) if self._times else (first, last)
        records = bytes(self._chunk)
        compressed = self._compress(records)
        start = self._stream.tell()
        self._stream.write(_record(Chunk(compression="zstd", data=compressed, message_start_time=first,
                                         message_end_time=last, uncompressed_crc=zlib.crc32(records),
                                         uncompressed_size=len(records))))
        index_start = self._stream.tell()
        offsets = {}
        for channel_id, pairs in indexes.items():
            offsets[channel_id] = self._stream.tell()
            data = pairs.tobytes()
            self._stream.write(_MESSAGE_INDEX.pack(Opcode.MESSAGE_INDEX, 2 + 4 + len(data), channel_id, len(data)))
            self._stream.write(data)
            self._counts[channel_id] += len(pairs)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=first, message_end_time=last, chunk_start_offset=start,
            chunk_length=index_start - start, message_index_offsets=offsets,
            message_index_length=self._stream.tell() - index_start, compression="zstd",
            compressed_size=len(compressed), uncompressed_size=len(records)))
        self._chunk = bytearray()
        self._indexes = defaultdict(list)
