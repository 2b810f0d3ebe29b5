"""Read an MCAP file's records from its bytes, trusting none of its claims.

Every length is checked against what the file (or the enclosing record) holds before anything is
read or allocated; a chunk is decompressed only when its uncompressed size, as the chunk record and
the ZSTD frame state it, fits in what is left of a budget of ``EXPANSION`` times the file's size
(plus ``MIN_BUDGET``): a crafted file cannot make the reader allocate more than that, however much it
claims. Every check MCAP offers is made: each chunk's CRC of its uncompressed records, the data
section's CRC (the ``DataEnd`` record), the summary's CRC (the footer), the summary's statistics
against what the data section holds, its chunk index against where the chunks are, and the closing
magic at the very end.

A record that cannot be read (cut off, damaged framing, a chunk that does not decompress or fails its
CRC) stops the reading: ``stopped`` says where and why, and the records before it have been yielded.
A check that fails without stopping is added to ``damage``.
"""
from __future__ import annotations

import struct
import zlib
from collections import Counter
from io import BytesIO
from typing import Iterator

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError
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
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

MAGIC = MCAP0_MAGIC  # the 8 bytes an MCAP file starts and ends with (the mcap library's, which the writer writes)
EXPANSION = 100  # the chunks of a file may hold at most this many times its size of uncompressed records
MIN_BUDGET = 1 << 20  # and at least this many bytes [B]
_PREFIX = struct.Struct("<BQ")  # opcode, record length
_FOOTER_FIELDS = 1 + 8 + 8 + 8  # opcode, length, summary start, summary offset start: what the summary CRC covers
_READERS = {Opcode.ATTACHMENT: Attachment.read, Opcode.ATTACHMENT_INDEX: AttachmentIndex.read,
            Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read, Opcode.CHUNK_INDEX: ChunkIndex.read,
            Opcode.DATA_END: DataEnd.read, Opcode.FOOTER: Footer.read, Opcode.HEADER: Header.read,
            Opcode.MESSAGE_INDEX: MessageIndex.read, Opcode.METADATA: Metadata.read,
            Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.SCHEMA: Schema.read, Opcode.STATISTICS: Statistics.read,
            Opcode.SUMMARY_OFFSET: SummaryOffset.read}
_IN_CHUNKS = (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE)


class Unreadable(Exception):
    """A record that cannot be read; the text says which and why."""


class _Exact(ReadDataStream):
    """A stream over one record's bytes that refuses to read past them (the library's returns what is left)."""

    def read(self, length: int) -> bytes:
        if length < 0:
            raise EndOfFile(f"a length of {length}")
        data = super().read(length)
        if len(data) != length:
            raise EndOfFile(f"{length} bytes claimed, {len(data)} left in the record")
        return data


def _name(opcode: int) -> str:
    return Opcode(opcode).name.lower() if opcode in Opcode._value2member_map_ else f"opcode 0x{opcode:02x}"


def parse(opcode: int, body: bytes) -> McapRecord | None:
    """The record of ``opcode`` whose bytes after its length are ``body``; None for an opcode MCAP does not
    define; Unreadable when the bytes do not hold the record."""
    stream = _Exact(BytesIO(body))
    try:
        if opcode == Opcode.MESSAGE:
            return Message.read(stream, len(body))
        reader = _READERS.get(opcode)
        return None if reader is None else reader(stream)
    except (McapError, struct.error, ValueError) as error:  # ValueError: UnicodeDecodeError in a string
        raise Unreadable(f"{_name(opcode)} record: {type(error).__name__}: {error}") from None


class McapScan:
    """The records of one MCAP file (``data``: its bytes, which start with the magic), read with ``records``."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.budget = EXPANSION * len(data) + MIN_BUDGET  # uncompressed bytes the chunks may still hold
        self.stopped: str | None = "the file ends before its footer"  # None once the footer and magic were read
        self.damage: list[str] = []
        self.messages: Counter[int] = Counter()  # messages read per channel id
        self.held: Counter[str] = Counter()  # records of the data section by kind: schema, channel, metadata, ...
        self.chunk_offsets: list[int] = []
        self.crcs: tuple[int, int] | None = None  # the data section's and the summary's CRC as the file states them
        self._statistics: Statistics | None = None
        self._data_crc = 0
        self._chunk_index: list[int] = []

    def records(self) -> Iterator[tuple[int, McapRecord]]:
        """(offset, record) of every record of the data section in order, those of a chunk with the chunk's
        offset; then the summary and footer are checked."""
        data = self.data
        at = len(MAGIC)
        data_end: int | None = None
        while True:
            if at + _PREFIX.size > len(data):
                self.stopped = (f"the file is cut off after {len(data)} bytes"
                                + (" inside a record's header" if at < len(data) else "")
                                + ("" if data_end is not None else ", before its summary and footer"))
                return
            opcode, length = _PREFIX.unpack_from(data, at)
            end = at + _PREFIX.size + length
            if end > len(data):
                self.stopped = (f"the file ends inside the {_name(opcode)} record at byte {at}, which claims {length} "
                                f"bytes where {len(data) - at - _PREFIX.size} are left (cut off, or a damaged length)")
                return
            try:
                record = parse(opcode, data[at + _PREFIX.size:end])
                if record is None:
                    self.damage.append(f"a record of unknown {_name(opcode)} at byte {at}")
                elif data_end is None:
                    if isinstance(record, Chunk):
                        inner = self._chunk_records(record)
                        self.chunk_offsets.append(at)
                        for item in inner:
                            self._count(item)
                            yield at, item
                    elif isinstance(record, DataEnd):
                        data_end = end
                        self._data_crc = record.data_section_crc
                        crc = zlib.crc32(memoryview(data)[:at])
                        if record.data_section_crc not in (0, crc):
                            self.damage.append(f"the data section's CRC is {crc:08x}, its DataEnd record says "
                                               f"{record.data_section_crc:08x}")
                    elif isinstance(record, Footer):
                        self.damage.append("the footer comes without a DataEnd record before it")
                        self._footer(record, at, end)
                        return
                    elif not isinstance(record, (Statistics, ChunkIndex, AttachmentIndex, MetadataIndex,
                                                 SummaryOffset)):
                        self._count(record)
                        yield at, record
                    else:
                        self.damage.append(f"a summary record ({_name(opcode)}) at byte {at}, in the data section")
                elif isinstance(record, Footer):
                    self._footer(record, at, end, data_end)
                    return
                elif isinstance(record, Statistics):
                    self._statistics = record
                elif isinstance(record, ChunkIndex):
                    self._chunk_index.append(record.chunk_start_offset)
                elif isinstance(record, (Chunk, Message, Metadata, Attachment, DataEnd, Header)):
                    self.damage.append(f"a {_name(opcode)} record at byte {at}, after the data section")
            except Unreadable as error:
                self.stopped = f"the file is damaged at byte {at}: {error}"
                return
            at = end

    def _count(self, record: McapRecord) -> None:
        if isinstance(record, Message):
            self.messages[record.channel_id] += 1
        else:
            self.held[type(record).__name__] += 1

    def _chunk_records(self, chunk: Chunk) -> list[McapRecord]:
        size = chunk.uncompressed_size
        if size > self.budget:
            raise Unreadable(f"a chunk claims {size} bytes of records, more than the {EXPANSION} times the file's "
                             "size a recording may hold")
        if chunk.compression == "zstd":
            try:
                declared = zstandard.frame_content_size(chunk.data)
                if declared not in (-1, size):
                    raise Unreadable(f"a chunk's ZSTD frame declares {declared} bytes, its record {size}")
                records = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=size)
            except zstandard.ZstdError as error:
                raise Unreadable(f"a chunk does not decompress (ZSTD: {error})") from None
        elif chunk.compression == "":
            records = chunk.data
        else:
            raise Unreadable(f"a chunk compressed with {chunk.compression!r}, which zencosim does not read")
        if len(records) != size:
            raise Unreadable(f"a chunk holds {len(records)} bytes of records where it claims {size}")
        self.budget -= size
        crc = zlib.crc32(records)
        if chunk.uncompressed_crc not in (0, crc):
            raise Unreadable(f"a chunk's records fail their CRC ({crc:08x}, the chunk says {chunk.uncompressed_crc:08x})")
        found, at = [], 0
        while at < len(records):
            if at + _PREFIX.size > len(records):
                raise Unreadable(f"a chunk ends inside the header of its record at byte {at}")
            opcode, length = _PREFIX.unpack_from(records, at)
            end = at + _PREFIX.size + length
            if end > len(records):
                raise Unreadable(f"a chunk's {_name(opcode)} record at byte {at} claims {length} bytes, "
                                 f"{len(records) - at - _PREFIX.size} are left")
            if opcode not in _IN_CHUNKS:
                raise Unreadable(f"a chunk holds a {_name(opcode)} record at byte {at}")
            found.append(parse(opcode, records[at + _PREFIX.size:end]))
            at = end
        return found

    def _footer(self, footer: Footer, at: int, end: int, data_end: int | None = None) -> None:
        """Check the summary (CRC, statistics, chunk index) and the closing magic; reading is complete."""
        data = self.data
        self.stopped = None
        self.crcs = (self._data_crc, footer.summary_crc)
        if data[end:] != MAGIC:
            self.damage.append(f"the file does not end with the MCAP magic right after its footer (byte {end}: "
                               f"{len(data) - end} bytes follow it)")
        if footer.summary_start and data_end is not None and footer.summary_start != data_end:
            self.damage.append(f"the footer puts the summary at byte {footer.summary_start}, it starts at {data_end}")
        if footer.summary_crc:
            crc = zlib.crc32(memoryview(data)[footer.summary_start or at:at + _FOOTER_FIELDS])
            if crc != footer.summary_crc:
                self.damage.append(f"the summary's CRC is {crc:08x}, the footer says {footer.summary_crc:08x}")
        stats = self._statistics
        if stats is None:
            return
        counted = {"messages": (stats.message_count, sum(self.messages.values())),
                   "chunks": (stats.chunk_count, len(self.chunk_offsets)),
                   "schemas": (stats.schema_count, self.held["Schema"]),
                   "channels": (stats.channel_count, self.held["Channel"]),
                   "metadata records": (stats.metadata_count, self.held["Metadata"]),
                   "attachments": (stats.attachment_count, self.held["Attachment"])}
        for what, (claimed, held) in counted.items():
            if claimed != held:
                self.damage.append(f"the summary counts {claimed} {what}, the file holds {held}")
        per_channel = {c: n for c, n in stats.channel_message_counts.items() if n}
        if per_channel != dict(self.messages):
            self.damage.append(f"the summary's messages per channel ({per_channel}) differ from the file's "
                               f"({dict(self.messages)})")
        if self._chunk_index and self._chunk_index != self.chunk_offsets:
            self.damage.append("the summary's chunk index points elsewhere than the chunks are")
