"""Encode a batch of wire messages into MCAP message records, vectorised with numpy.

The recorder receives the messages of a run in batches of about two thousand (``recordings.recorder``).
Messages of one channel with the same kind and shape (rows, count) have the same typed protobuf
layout (``recordings.schema``): their records differ only in the header fields and the values. So a
batch is validated at once (version, kind, size and rows of every header, as
``manager.wire.protocol.decode_header`` does), grouped by layout, and each group's records are built
by one gather from a table of its variable bytes (step, time, simulated time, reference, log time,
payload) and its constant bytes (MCAP record header, protobuf tags and lengths, kind, rows). The
records go back into the order of the batch, so every channel keeps its order. An ERROR message
(a text payload) is encoded on its own; a malformed message is described and left out.

Every value is copied as its eight bytes: NaN payloads, -0.0 and infinities are recorded bit for bit.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable

import numpy as np

from zencosim.manager.wire.protocol import HEADER, HEADER_DTYPE, VERSION, Kind, ProtocolError, decode_header
from zencosim.recordings.schema import HEADER_FIELDS, ChannelSchema, tag, varint

_KINDS = np.zeros(256, dtype=bool)
_KINDS[[kind.value for kind in Kind]] = True
_MCAP_MESSAGE = struct.Struct("<BQHI")  # opcode, record length, channel id, sequence; then log and publish time
_OPCODE_MESSAGE = 0x05
# the variable bytes of one message, in the table a group's records are gathered from
STEP_AT, TIME_AT, SIM_AT, REF_AT, LOG_AT, PAYLOAD_AT = 0, 8, 16, 24, 28, 36


@dataclass
class EncodedBatch:
    """The records of a batch in its order, and per record its channel index, log time and offset."""

    records: np.ndarray  # uint8: the records one after the other (a copy to bytes cost 4 % of the recorder's time)
    channels: np.ndarray  # int64 channel index per record
    log_times: np.ndarray  # int64 [ns]
    offsets: np.ndarray  # int64 offset of each record in ``records``
    malformed: list[str]  # why each left-out message was malformed
    carry: int  # the stamp of the batch's last status: it also stamps the first messages of the next batch


def body_pieces(schema: ChannelSchema, kind: int, rows: int, count: int) -> list[bytes | tuple[int, int]]:
    """The protobuf body of a message of this layout: constant bytes, or (offset, length) in the variable table."""
    pieces: list[bytes | tuple[int, int]] = [tag(HEADER_FIELDS["step"], 1), (STEP_AT, 8), tag(HEADER_FIELDS["time_ns"], 1),
                                             (TIME_AT, 8), tag(HEADER_FIELDS["kind"], 0) + varint(kind),
                                             tag(HEADER_FIELDS["rows"], 5) + struct.pack("<I", rows),
                                             tag(HEADER_FIELDS["ref"], 5), (REF_AT, 4),
                                             tag(HEADER_FIELDS["sim_time"], 1), (SIM_AT, 8)]
    n = len(schema.slots)
    if not (schema.named(kind, rows) and count == max(rows, 1) * n):
        if count:
            pieces += [tag(HEADER_FIELDS["values"], 2) + varint(8 * count), (PAYLOAD_AT, 8 * count)]
        return pieces
    def value(j: int) -> tuple[int, int]:
        return PAYLOAD_AT + 8 * j, 8

    done: set[int] = set()
    for j, slot in enumerate(schema.slots):
        if schema.role == "inputs":
            pieces.append(tag(slot.number, 2) + varint(8 * rows))
            pieces += [value(i * n + j) for i in range(rows)]
        elif slot.outer is None:
            pieces += [tag(slot.number, 1), value(j)]
        elif slot.outer not in done:
            done.add(slot.outer)
            members = [(k, s.number) for k, s in enumerate(schema.slots) if s.outer == slot.outer]
            pieces.append(tag(slot.outer, 2) + varint(9 * len(members)))
            for k, number in members:
                pieces += [tag(number, 1), value(k)]
    return pieces


class _GroupLayout:
    """How to build the records of one (channel, kind, rows, count) group: a gather map over a table whose
    rows are the messages' variable bytes followed by the layout's constant bytes."""

    def __init__(self, schema: ChannelSchema, channel_id: int, kind: int, rows: int, count: int) -> None:
        self.variable = PAYLOAD_AT + 8 * count
        body = body_pieces(schema, kind, rows, count)
        body_size = sum(len(p) if isinstance(p, bytes) else p[1] for p in body)
        prefix = _MCAP_MESSAGE.pack(_OPCODE_MESSAGE, 2 + 4 + 8 + 8 + body_size, channel_id, 0)
        pieces = [prefix, (LOG_AT, 8), (LOG_AT, 8)] + body  # log time and publish time: the wall clock
        constant = bytearray()
        gather: list[np.ndarray] = []
        for piece in pieces:
            if isinstance(piece, bytes):
                gather.append(np.arange(len(piece)) + self.variable + len(constant))
                constant += piece
            else:
                gather.append(np.arange(piece[0], piece[0] + piece[1]))
        fields = [("step", "<i8", STEP_AT), ("time_ns", "<i8", TIME_AT), ("sim_time", "<f8", SIM_AT),
                  ("ref", "<u4", REF_AT), ("log_time", "<i8", LOG_AT)] + (
                     [("payload", f"V{8 * count}", PAYLOAD_AT)] if count else []) + [
                     ("constant", f"V{len(constant)}", self.variable)]
        names, formats, offsets = zip(*fields)
        self.dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                               "itemsize": self.variable + len(constant)})
        self.constant = np.void(bytes(constant))
        self.gather = np.concatenate(gather)
        self.size = self.gather.size

    def table(self, n: int) -> np.ndarray:
        """The table of ``n`` messages (a structured array, one row each), its constant bytes filled in."""
        table = np.empty(n, dtype=self.dtype)
        table["constant"] = self.constant
        return table

    def records(self, table: np.ndarray) -> np.ndarray:
        """The records of the messages of ``table``, one row of bytes each (C-contiguous)."""
        return np.take(table.view(np.uint8).reshape(len(table), self.dtype.itemsize), self.gather, axis=1)


def _items(buffer: np.ndarray, width: int) -> np.ndarray:
    """Every ``width`` bytes of ``buffer`` (uint8, contiguous) as one item of that many bytes, one from each byte on
    (a view: item ``k`` is ``buffer[k:k + width]``). Indexed with the starts of rows, it gathers or scatters them a
    row at a time, where a gather of each byte (``buffer[starts[:, None] + np.arange(width)]``) took 23 times as long
    for 107-byte rows, and a strided two-dimensional copy, byte by byte, 2 to 6 times."""
    return np.ndarray((buffer.size - width + 1,), dtype=f"V{width}", buffer=buffer, strides=(1,))


def write_rows(out: np.ndarray, starts: np.ndarray, rows: np.ndarray) -> None:
    """Write each row of ``rows`` (uint8, two-dimensional) into ``out`` at its start, a row at a time (``_items``)."""
    rows = np.ascontiguousarray(rows)
    _items(out, rows.shape[1])[starts] = rows.view(f"V{rows.shape[1]}")[:, 0]


def wire_headers(sizes: np.ndarray, data: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start, header and validity of each message) of wire messages one after the other in ``data`` (uint8),
    of ``sizes``; a message is valid as ``manager.wire.protocol.decode_header`` would accept it."""
    starts = np.cumsum(sizes, dtype=np.int64) - sizes
    whole = sizes >= HEADER.size
    heads = np.zeros(sizes.size, dtype=HEADER_DTYPE)
    if whole.any():
        heads[whole] = _items(data, HEADER.size)[starts[whole]].view(HEADER_DTYPE)
    kinds = heads["kind"]
    item = np.where(kinds == Kind.ERROR, 1, 8)
    valid = (whole & (heads["version"] == VERSION) & _KINDS[kinds]
             & (sizes == HEADER.size + item * heads["count"].astype(np.int64))
             & (heads["count"] % np.maximum(heads["rows"], 1) == 0))
    return starts, heads, valid


def _fault(wire: bytes, sender: str) -> str:
    """What ``decode_header`` finds wrong with a message that the vectorised checks rejected."""
    try:
        decode_header(wire, sender)
    except ProtocolError as error:
        return str(error)
    raise AssertionError(f"message from {sender}: rejected, but its header is valid")


class BatchEncoder:
    """Encodes batches of the wire messages of ``schemas``' channels (MCAP channel ids ``channel_ids``);
    ``status`` is the index of the status channel, whose messages carry the batch's stamps."""

    def __init__(self, schemas: list[ChannelSchema], channel_ids: list[int], status: int) -> None:
        self.schemas = schemas
        self.channel_ids = channel_ids
        self.status = status
        self._layouts: dict[tuple[int, int, int, int], _GroupLayout] = {}

    def encode(self, channels: np.ndarray, sizes: np.ndarray, stamps: np.ndarray, blob: bytes, carry: int,
               describe: Callable[[int], str]) -> EncodedBatch:
        """The records of the messages ``blob`` holds one after the other (``sizes``), of ``channels``; a
        status message takes the next of ``stamps``; ``describe(i)`` names message ``i`` in an error."""
        data = np.frombuffer(blob, dtype=np.uint8)
        n = channels.size
        starts, heads, valid = wire_headers(sizes, data)
        kinds = heads["kind"]
        malformed = [_fault(blob[starts[i]:starts[i] + sizes[i]], describe(i)) for i in np.flatnonzero(~valid).tolist()]
        status_rank = np.cumsum(channels == self.status)
        stamped = np.concatenate(([carry], stamps)).astype(np.int64)
        log_times = stamped[status_rank]
        carry = int(stamped[-1])

        keys = ((channels.astype(np.uint64) << 56) | (kinds.astype(np.uint64) << 48)
                | (heads["rows"].astype(np.uint64) << 32) | heads["count"].astype(np.uint64))
        errors = valid & (kinds == Kind.ERROR)
        grouped = valid & ~errors
        record_sizes = np.zeros(n, dtype=np.int64)
        groups = []
        unique, inverse = np.unique(keys[grouped], return_inverse=True)
        members_of = np.flatnonzero(grouped)
        for g, key in enumerate(unique.tolist()):
            members = members_of[inverse == g]
            layout = self._layout(key)
            record_sizes[members] = layout.size
            groups.append((members, layout))
        error_records = {}
        for i in np.flatnonzero(errors).tolist():
            error_records[i] = self._error_record(int(channels[i]), heads[i], blob[starts[i] + HEADER.size:
                                                                                    starts[i] + sizes[i]], int(log_times[i]))
            record_sizes[i] = len(error_records[i])
        offsets = np.cumsum(record_sizes) - record_sizes
        out = np.empty(int(record_sizes.sum()), dtype=np.uint8)
        for members, layout in groups:
            table = layout.table(members.size)
            heads_m = heads[members]
            table["step"], table["time_ns"], table["ref"] = heads_m["step"], heads_m["time_ns"], heads_m["ref"]
            table["sim_time"], table["log_time"] = heads_m["time_ns"] * 1e-9, log_times[members]
            if layout.variable > PAYLOAD_AT:
                table["payload"] = _items(data, layout.variable - PAYLOAD_AT)[starts[members] + HEADER.size]
            write_rows(out, offsets[members], layout.records(table))
        for i, record in error_records.items():
            out[offsets[i]:offsets[i] + len(record)] = np.frombuffer(record, dtype=np.uint8)
        kept = np.flatnonzero(valid)
        return EncodedBatch(out, channels[kept].astype(np.int64), log_times[kept], offsets[kept], malformed,
                            carry)

    def _layout(self, key: int) -> _GroupLayout:
        layout = self._layouts.get(key)
        if layout is None:
            channel, kind, rows, count = key >> 56, (key >> 48) & 0xFF, (key >> 32) & 0xFFFF, key & 0xFFFFFFFF
            layout = _GroupLayout(self.schemas[channel], self.channel_ids[channel], kind, rows, count)
            self._layouts[key] = layout
        return layout

    def _error_record(self, channel: int, head, text: bytes, log_time: int) -> bytes:
        body = (tag(HEADER_FIELDS["step"], 1) + struct.pack("<q", int(head["step"]))
                + tag(HEADER_FIELDS["time_ns"], 1) + struct.pack("<q", int(head["time_ns"]))
                + tag(HEADER_FIELDS["kind"], 0) + varint(Kind.ERROR) + tag(HEADER_FIELDS["rows"], 5) + struct.pack("<I", 0)
                + tag(HEADER_FIELDS["ref"], 5) + struct.pack("<I", int(head["ref"]))
                + tag(HEADER_FIELDS["sim_time"], 1) + struct.pack("<d", int(head["time_ns"]) * 1e-9)
                + tag(HEADER_FIELDS["text"], 2) + varint(len(text)) + text)
        return (_MCAP_MESSAGE.pack(_OPCODE_MESSAGE, 2 + 4 + 8 + 8 + len(body), self.channel_ids[channel], 0)
                + struct.pack("<QQ", log_time, log_time) + body)
