"""The message encoding of a recording: protobuf, one message type per channel, its fields named by the scene.

A channel's messages are one typed message (``ChannelSchema``), so Foxglove, ``mcap cat`` and any
protobuf decoder show the scene's signal names without reading zencosim's metadata::

    syntax = "proto3";
    package zencosim.S2;                      // the subsystem (zencosim.manager for the status)
    import "zencosim/kind.proto";             // enum zencosim.Kind { KIND_UNSPECIFIED = 0; KIND_INIT = 1; ... }
    message Outputs {                         // <sub>/y; <sub>/commands is Commands, manager/status is Status
      sfixed64 step = 1;                      // communication point on the base macro-step grid
      sfixed64 time_ns = 2;                   // simulated time [ns], exact
      zencosim.Kind kind = 3;
      fixed32 rows = 4;                       // rows of a polynomial payload (commands), else 0
      repeated double values = 5;             // values of a message the named fields do not describe (PROJECT)
      string text = 6;                        // ERROR: the reason
      fixed32 ref = 7;                        // a reply: CRC-32 of the command it answers
      double sim_time = 8;                    // simulated time [s], for plotting
      double x2 = 16;                         // [m]   one field per output, in port order
      double v2 = 17;                         // [m/s]
      double energy = 18;                     // [J]
    }

In ``Commands`` each input is a ``repeated double`` holding its polynomial coefficients (the value
at the start of the step first, then the coefficients of ``tau``, ``tau**2``); the input ``x2*`` (the
received ``x2``) is the field ``x2``. In ``Status`` a dotted field ``delta_p.c`` is the field ``c`` of
the nested message ``delta_p`` (type ``DeltaP``), so a message path reads ``/manager/status.delta_p.c``.
Units are in each field's comment in the schema (``SourceCodeInfo``) and in the channel's metadata.
Names that are not protobuf identifiers are spelled with ``_`` (``field_names``).

Fields 1–7 are those of the one generic ``zencosim.Message`` of format 1 recordings (with ``kind`` then
a ``fixed32``), so :func:`decode` reads both formats. The schema is written by hand as a
``FileDescriptorSet``: the recorder needs no protobuf runtime. Encoding, vectorised over a batch of
wire messages, is ``recordings.encoding``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.layout import ChannelSpec

SCHEMA_ENCODING = "protobuf"
MESSAGE_ENCODING = "protobuf"
KIND_FILE = "zencosim/kind.proto"
HEADER_FIELDS = {"step": 1, "time_ns": 2, "kind": 3, "rows": 4, "values": 5, "text": 6, "ref": 7, "sim_time": 8}
FIRST_SIGNAL = 16  # field number of a channel's first named value
MESSAGE_NAMES = {"inputs": "Commands", "outputs": "Outputs", "status": "Status"}

_DOUBLE, _STRING, _FIXED32, _MESSAGE, _ENUM, _SFIXED64 = 1, 9, 7, 11, 14, 16  # FieldDescriptorProto.Type
_HEADER_TYPES = {"step": _SFIXED64, "time_ns": _SFIXED64, "kind": _ENUM, "rows": _FIXED32, "values": _DOUBLE,
                 "text": _STRING, "ref": _FIXED32, "sim_time": _DOUBLE}


def varint(n: int) -> bytes:
    out = bytearray()
    while n > 0x7F:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def tag(number: int, wire_type: int) -> bytes:
    return varint(number << 3 | wire_type)


def _length_delimited(field: int, data: bytes) -> bytes:
    return tag(field, 2) + varint(len(data)) + data


def identifier(name: str) -> str:
    """``name`` as a protobuf identifier: a received input loses its ``*``, other characters become ``_``."""
    text = re.sub(r"[^A-Za-z0-9_]", "_", name.removesuffix("*"))
    return text if re.match(r"[A-Za-z_]", text) else f"_{text}"


def _camel(name: str) -> str:
    return "".join(part[:1].upper() + part[1:] for part in name.split("_") if part) or "Fields"


def _field(name: str, number: int, type_: int, repeated: bool = False, type_name: str = "") -> bytes:
    """A FieldDescriptorProto: name 1, number 3, label 4, type 5, type_name 6, json_name 10."""
    json_name = name.split("_")[0] + "".join(part.title() for part in name.split("_")[1:])
    return (_length_delimited(1, name.encode()) + tag(3, 0) + varint(number)
            + tag(4, 0) + varint(3 if repeated else 1) + tag(5, 0) + varint(type_)
            + (_length_delimited(6, type_name.encode()) if type_name else b"")
            + _length_delimited(10, json_name.encode()))


def _kind_file() -> bytes:
    """kind.proto: ``enum zencosim.Kind`` with every kind of ``manager.wire.protocol``."""
    values = [("KIND_UNSPECIFIED", 0)] + [(f"KIND_{kind.name}", kind.value) for kind in Kind]
    enum = _length_delimited(1, b"Kind") + b"".join(
        _length_delimited(2, _length_delimited(1, name.encode()) + tag(2, 0) + varint(number)) for name, number in values)
    return (_length_delimited(1, KIND_FILE.encode()) + _length_delimited(2, b"zencosim")
            + _length_delimited(5, enum) + _length_delimited(12, b"proto3"))


@dataclass(frozen=True)
class Slot:
    """Where value ``index`` of a wire message sits in the typed message: field ``number`` (in the nested
    message field ``outer`` when not None); ``row`` is its row of a polynomial (commands)."""

    number: int
    outer: int | None = None


class ChannelSchema:
    """The typed message of one channel (see the module text)."""

    def __init__(self, spec: ChannelSpec) -> None:
        self.spec = spec
        self.role = spec.role
        source = identifier(spec.source)
        self.package = f"zencosim.{source if source not in ('Kind', 'zencosim') else source + '_'}"
        self.name = f"{self.package}.{MESSAGE_NAMES[spec.role]}"
        self.slots: list[Slot] = []  # one per name of the spec, in order
        self.groups: dict[str, tuple[int, list[tuple[str, int, str]]]] = {}  # status prefix → (field, inner fields)
        fields: list[tuple[str, int, str]] = []  # top-level named fields: (field name, number, unit)
        used = set(HEADER_FIELDS)
        for name, unit in zip(spec.names, spec.units):
            prefix, dot, suffix = name.partition(".")
            if spec.role == "status" and dot:
                outer = identifier(prefix)
                if outer not in self.groups:
                    self.groups[outer] = (FIRST_SIGNAL + len(fields) + len(self.groups), [])
                    used.add(outer)
                number, inner = self.groups[outer]
                self.slots.append(Slot(len(inner) + 1, number))
                inner.append((_unique(identifier(suffix), {f for f, _, _ in inner}), len(inner) + 1, unit))
                continue
            field_name = _unique(identifier(name), used)
            used.add(field_name)
            number = FIRST_SIGNAL + len(fields) + len(self.groups)
            fields.append((field_name, number, unit))
            self.slots.append(Slot(number))
        self.field_names = tuple(f for f, _, _ in fields)
        self.descriptor_set = self._descriptor_set(fields)

    def _descriptor_set(self, fields: list[tuple[str, int, str]]) -> bytes:
        """FileDescriptorSet: kind.proto and this channel's file, with each named field's unit as its comment."""
        message_name = MESSAGE_NAMES[self.role]
        body = _length_delimited(1, message_name.encode())
        comments: list[tuple[list[int], str]] = []  # (path in the file, trailing comment)
        index = 0
        for name, number in HEADER_FIELDS.items():
            body += _length_delimited(2, _field(name, number, _HEADER_TYPES[name], repeated=name == "values",
                                                type_name=".zencosim.Kind" if name == "kind" else ""))
            index += 1
        repeated = self.role == "inputs"
        for name, number, unit in fields:
            body += _length_delimited(2, _field(name, number, _DOUBLE, repeated))
            comments.append(([4, 0, 2, index], f" [{unit}]" + (" polynomial coefficients, constant first" if repeated else "")))
            index += 1
        for nested, (outer, (number, inner)) in enumerate(self.groups.items()):
            type_name = _camel(outer)
            body += _length_delimited(2, _field(outer, number, _MESSAGE, type_name=f".{self.package}.{message_name}.{type_name}"))
            body += _length_delimited(3, _length_delimited(1, type_name.encode()) + b"".join(
                _length_delimited(2, _field(name, n, _DOUBLE)) for name, n, _ in inner))
            for k, (_, _, unit) in enumerate(inner):
                comments.append(([4, 0, 3, nested, 2, k], f" [{unit}]"))
        locations = b"".join(_length_delimited(1, _length_delimited(1, b"".join(varint(p) for p in path))
                                               + _length_delimited(4, text.encode())) for path, text in comments)
        file = (_length_delimited(1, f"zencosim/{self.package.split('.', 1)[1]}.proto".encode())
                + _length_delimited(2, self.package.encode()) + _length_delimited(3, KIND_FILE.encode())
                + _length_delimited(4, body) + _length_delimited(9, locations) + _length_delimited(12, b"proto3"))
        return _length_delimited(1, _kind_file()) + _length_delimited(1, file)


    def named(self, kind: int, rows: int) -> bool:
        """Whether a message of ``kind`` (with ``rows``) holds the channel's named values, absent or not."""
        if self.role == "inputs":
            return rows > 0
        return kind == (Kind.OUTPUT if self.role == "outputs" else Kind.STATUS)


def _unique(name: str, used) -> str:
    while name in used:
        name += "_"
    return name


@dataclass(frozen=True)
class StoredMessage:
    """One decoded message of a recording, as the wire message it was: values in wire order."""

    step: int
    time_ns: int
    kind: int
    rows: int
    values: np.ndarray  # float64
    text: str
    ref: int


def _read_varint(data: bytes, at: int) -> tuple[int, int]:
    """A protobuf varint at ``at`` and the position after it; ValueError for one that no 64-bit field holds
    (damaged bytes: a longer one would reach numpy's int64 arrays as an OverflowError)."""
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            if value >> 64:
                raise ValueError("a varint beyond 64 bits")
            return value, at
        shift += 7
        if shift >= 70:
            raise ValueError("a varint of more than 10 bytes")


def _fields(data: bytes) -> dict[int, list[int | bytes]]:
    """Every field of a protobuf message: number → its occurrences (varints as int, the rest as bytes)."""
    fields: dict[int, list[int | bytes]] = {}
    at, end = 0, len(data)
    try:
        while at < end:
            key, at = _read_varint(data, at)
            number, wire_type = key >> 3, key & 7
            if wire_type == 0:
                value, at = _read_varint(data, at)
                fields.setdefault(number, []).append(value)
                continue
            if wire_type == 2:
                size, at = _read_varint(data, at)
            elif wire_type in (1, 5):
                size = 8 if wire_type == 1 else 4
            else:
                raise ValueError(f"unsupported protobuf wire type {wire_type}")
            if at + size > end:
                raise IndexError
            fields.setdefault(number, []).append(data[at:at + size])
            at += size
    except IndexError:
        raise ValueError("truncated protobuf message") from None
    return fields


def _doubles(occurrences: list) -> np.ndarray:
    payload = b"".join(occurrences)
    if len(payload) % 8:
        raise ValueError("a double field that is not a whole number of float64")
    return np.frombuffer(payload, dtype="<f8")


def decode(data: bytes, schema: ChannelSchema | None = None) -> StoredMessage:
    """A channel's message (any valid protobuf encoding; ``schema`` None: a format 1 ``zencosim.Message``);
    ValueError when malformed."""
    fields = _fields(data)

    def integer(name: str, size: int, signed: bool) -> int:
        raw = fields.get(HEADER_FIELDS[name], [0])[-1]
        if isinstance(raw, bytes):
            if len(raw) != size:
                raise ValueError(f"field {name}: expected {size} bytes, got {len(raw)}")
            return int.from_bytes(raw, "little", signed=signed)
        return raw - (1 << 64) if signed and raw >= 1 << 63 else raw

    rows, kind = integer("rows", 4, False), integer("kind", 4, False)
    values = _doubles(fields.get(HEADER_FIELDS["values"], []))
    if schema is not None and not values.size and schema.named(kind, rows):
        values = _named_values(fields, schema, rows)
    text = fields.get(HEADER_FIELDS["text"], [b""])[-1]
    return StoredMessage(integer("step", 8, True), integer("time_ns", 8, True), kind, rows,
                         values, text.decode("utf-8", "replace") if isinstance(text, bytes) else "",
                         integer("ref", 4, False))


def _named_values(fields: dict, schema: ChannelSchema, rows: int) -> np.ndarray:
    """The wire-order values of a message's named fields; a field that is absent is 0.0 (proto3 leaves out
    a field that holds its default)."""
    nested: dict[int, dict] = {}
    columns = []
    for slot in schema.slots:
        if slot.outer is None:
            found = fields.get(slot.number, [])
        else:
            if slot.outer not in nested:
                nested[slot.outer] = _fields(b"".join(fields.get(slot.outer, [])))
            found = nested[slot.outer].get(slot.number, [])
        if schema.role == "inputs":
            column = _doubles(found) if found else np.zeros(rows)
            if column.size != rows:
                raise ValueError(f"expected {rows} coefficients of {schema.spec.names[len(columns)]}, got {column.size}")
        else:
            column = _doubles(found[-1:]) if found else np.zeros(1)
        columns.append(column)
    return np.column_stack(columns).ravel() if columns else np.zeros(0)  # a subsystem without inputs
