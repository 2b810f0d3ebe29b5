"""The message encoding of a recording: protobuf, one message type for every channel.

Every wire message of a run (``manager.wire.protocol``) is stored as one ``zencosim.Message``::

    syntax = "proto3";
    package zencosim;
    message Message {
      sfixed64 step = 1;           // communication point on the base macro-step grid
      sfixed64 time_ns = 2;        // simulated time [ns]
      fixed32 kind = 3;            // manager.wire.protocol.Kind: INIT 1, STEP 2, ..., OUTPUT 16, ..., STATUS 32
      fixed32 rows = 4;            // rows of a polynomial payload (order + 1), else 0
      repeated double values = 5;  // packed; named by the channel's metadata (recordings.layout)
      string text = 6;             // ERROR: the reason
      fixed32 ref = 7;             // a reply: CRC-32 of the command it answers
    }

A packed ``repeated double`` is the count of bytes followed by the little-endian float64 values, which
is exactly the wire payload: encoding copies the payload as it is, so every float64 (NaN and -0.0
included) round-trips bit for bit. Fixed-width header fields make the encoder one ``struct.pack``;
after ZSTD they cost no more than varints (docs/recording.md has the measurements). The schema is
written by hand as a ``FileDescriptorSet`` so that the recorder needs no protobuf runtime, and any
protobuf decoder (the ``mcap`` tools, Foxglove, ``mcap-protobuf-support``) reads the messages.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from zencosim.manager.wire.protocol import HEADER, Kind, decode_header

SCHEMA_NAME = "zencosim.Message"
SCHEMA_ENCODING = "protobuf"
MESSAGE_ENCODING = "protobuf"

_HEAD = struct.Struct("<BqBqBIBIBI")  # tags and values of fields 1-4 and 7
_VALUES_TAG = 0x2A  # field 5, length-delimited
_TEXT_TAG = 0x32  # field 6, length-delimited


def _varint(n: int) -> bytes:
    out = bytearray()
    while n > 0x7F:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def _length_delimited(field: int, data: bytes) -> bytes:
    return _varint(field << 3 | 2) + _varint(len(data)) + data


def _field(name: str, number: int, type_: int, repeated: bool = False) -> bytes:
    """A FieldDescriptorProto: name 1, number 3, label 4, type 5, json_name 10."""
    json_name = name.split("_")[0] + "".join(part.title() for part in name.split("_")[1:])
    return (_length_delimited(1, name.encode()) + _varint(3 << 3) + _varint(number)
            + _varint(4 << 3) + _varint(3 if repeated else 1) + _varint(5 << 3) + _varint(type_)
            + _length_delimited(10, json_name.encode()))


_DOUBLE, _STRING, _FIXED32, _SFIXED64 = 1, 9, 7, 16  # FieldDescriptorProto.Type

FILE_DESCRIPTOR_SET: bytes = _length_delimited(1, (  # FileDescriptorSet.file
    _length_delimited(1, b"zencosim/message.proto")  # FileDescriptorProto.name
    + _length_delimited(2, b"zencosim")  # package
    + _length_delimited(4, (  # message_type: DescriptorProto
        _length_delimited(1, b"Message")
        + _length_delimited(2, _field("step", 1, _SFIXED64))
        + _length_delimited(2, _field("time_ns", 2, _SFIXED64))
        + _length_delimited(2, _field("kind", 3, _FIXED32))
        + _length_delimited(2, _field("rows", 4, _FIXED32))
        + _length_delimited(2, _field("values", 5, _DOUBLE, repeated=True))
        + _length_delimited(2, _field("text", 6, _STRING))
        + _length_delimited(2, _field("ref", 7, _FIXED32))))
    + _length_delimited(12, b"proto3")))  # syntax


def encode_wire(wire: bytes, sender: str) -> tuple[int, bytes]:
    """(simulated time [ns], ``zencosim.Message`` bytes) of one wire message, validated by
    ``manager.wire.protocol.decode_header`` (its ProtocolError names ``sender``)."""
    kind, rows, _count, step, time_ns, ref = decode_header(wire, sender)
    head = _HEAD.pack(0x09, step, 0x11, time_ns, 0x1D, kind, 0x25, rows, 0x3D, ref)
    if len(wire) == HEADER.size:
        return time_ns, head
    payload = wire[HEADER.size:]
    return time_ns, head + (_TEXT_TAG if kind == Kind.ERROR else _VALUES_TAG).to_bytes() + _varint(len(payload)) + payload


@dataclass(frozen=True)
class StoredMessage:
    """One decoded ``zencosim.Message``."""

    step: int
    time_ns: int
    kind: int
    rows: int
    values: np.ndarray  # float64
    text: str
    ref: int


def _read_varint(data: bytes, at: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, at
        shift += 7


def decode_stored(data: bytes) -> StoredMessage:
    """Decode a ``zencosim.Message`` in any valid protobuf encoding; raise ValueError when malformed."""
    fields: dict[int, int | bytes] = {}
    values: list[bytes] = []
    at, end = 0, len(data)
    try:
        while at < end:
            tag, at = _read_varint(data, at)
            number, wire_type = tag >> 3, tag & 7
            if wire_type == 0:
                fields[number], at = _read_varint(data, at)
                continue
            if wire_type == 2:
                size, at = _read_varint(data, at)
            elif wire_type in (1, 5):
                size = 8 if wire_type == 1 else 4
            else:
                raise ValueError(f"unsupported protobuf wire type {wire_type}")
            if at + size > end:
                raise IndexError
            chunk, at = data[at:at + size], at + size
            if number == 5:
                values.append(chunk)
            else:
                fields[number] = chunk
    except IndexError:
        raise ValueError("truncated protobuf message") from None

    def integer(number: int, size: int, signed: bool) -> int:
        raw = fields.get(number, 0)
        if isinstance(raw, bytes):
            if len(raw) != size:
                raise ValueError(f"field {number}: expected {size} bytes, got {len(raw)}")
            return int.from_bytes(raw, "little", signed=signed)
        return raw - (1 << 64) if signed and raw >= 1 << 63 else raw

    payload = b"".join(values)
    if len(payload) % 8:
        raise ValueError("values: not a whole number of float64")
    text = fields.get(6, b"")
    return StoredMessage(integer(1, 8, True), integer(2, 8, True), integer(3, 4, False), integer(4, 4, False),
                         np.frombuffer(payload, dtype="<f8"),
                         text.decode("utf-8", "replace") if isinstance(text, bytes) else "", integer(7, 4, False))
