"""The wire protocol: a fixed 32-byte header and little-endian float64 values. Nothing executes on decode.

Header (little endian): version u8, kind u8, rows u16 (rows of a polynomial payload, else 0),
count u32 (number of float64 values; for ERROR the number of UTF-8 bytes), step i64 (index of the
communication point on the base macro-step grid), time i64 [ns], ref u32 (a reply: the CRC-32 of the command it
answers; a STEP: its length in base macro-steps, 0 for the subsystem's communication step — an energy-controlled
run's steps vary: ``manager.scheme.energy_step``), 4 bytes of padding. The same ``encode``/``decode`` run
over Zenoh and by the in-process implicit scheme (the in-process Jacobi scheme hands arrays, and encodes for a
recording's tap only: ``manager.bus.inproc``).
"""
from __future__ import annotations

import functools
import struct
import zlib
from enum import IntEnum
from typing import NamedTuple

import numpy as np

from zencosim.manager.wire.text import printable
from zencosim.versions import WIRE_PROTOCOL as VERSION

HEADER = struct.Struct("<BBHIqqI4x")
HEADER_DTYPE = np.dtype([("version", "u1"), ("kind", "u1"), ("rows", "<u2"), ("count", "<u4"), ("step", "<i8"),
                         ("time_ns", "<i8"), ("ref", "<u4"), ("pad", "V4")])  # HEADER as a numpy record
assert HEADER_DTYPE.itemsize == HEADER.size


class Kind(IntEnum):
    INIT = 1  # manager → subsystem: constant inputs at t0; reply OUTPUT at step 0
    STEP = 2  # manager → subsystem: input polynomial over the next communication step; reply OUTPUT
    SAVE = 3  # manager → subsystem: keep the state at this step; reply ACK
    RESTORE = 4  # manager → subsystem: go back to the state saved at this step; reply ACK
    STOP = 5  # manager → subsystem process, on <sub>/u: end the process (no reply)
    PROJECT = 6  # manager → subsystem: move joint points by the given corrections; reply OUTPUT (same step)
    OUTPUT = 16  # subsystem → manager: output values at a communication point
    ACK = 17  # subsystem → manager
    ERROR = 18  # subsystem → manager: the command failed; the payload is the reason (UTF-8)
    STATUS = 32  # manager → observers: the status after a macro-step, fields named by manager.wire.status


_KINDS = {kind.value: kind for kind in Kind}
_ITEMSIZE = {kind: (1 if kind == Kind.ERROR else 8) for kind in Kind}
_F8 = np.dtype("<f8")
_DTYPE = {kind: (np.dtype(np.uint8) if kind == Kind.ERROR else _F8) for kind in Kind}


class ProtocolError(ValueError):
    """A malformed, unexpected or out-of-order message."""


class Message(NamedTuple):  # a tuple: built for every message a subsystem takes, in a fraction of a dataclass's time
    kind: Kind
    step: int
    time_ns: int
    rows: int
    ref: int  # replies: CRC-32 of the command answered; STEP: its length in base steps (0: the communication step)
    values: np.ndarray  # read-only view of the payload

    def text(self) -> str:
        """An ERROR's reason, its control characters escaped (``manager.wire.text``: it came from the network)."""
        return printable(self.values.tobytes().decode("utf-8", errors="replace"))


def encode(kind: Kind, step: int, time_ns: int, values: np.ndarray | None = None, rows: int = 0, ref: int = 0) -> bytes:
    if values is None:
        return HEADER.pack(VERSION, kind, 0, 0, step, time_ns, ref)
    return HEADER.pack(VERSION, kind, rows, values.size, step, time_ns, ref) + values.astype(_F8, copy=False).tobytes()


def encode_error(step: int, time_ns: int, reason: str, ref: int = 0) -> bytes:
    text = reason.encode("utf-8")
    return HEADER.pack(VERSION, Kind.ERROR, 0, len(text), step, time_ns, ref) + text


def split_messages(batch: bytes, sender: str) -> list[bytes]:
    """The messages of a batch: messages one after the other (the length of each from its header), as a
    subsystem sends its replies to the manager (``subsystems.process.host``)."""
    messages, at = [], 0
    while at < len(batch):
        if len(batch) - at < HEADER.size:
            raise ProtocolError(f"batch from {sender}: {len(batch) - at} bytes after the last message")
        size = HEADER.size + _ITEMSIZE.get(batch[at + 1], 8) * HEADER.unpack_from(batch, at)[3]
        messages.append(batch[at:at + size])
        at += size
    if at != len(batch):
        raise ProtocolError(f"batch from {sender}: its last message is cut short")
    return messages


def command_ref(command: bytes) -> int:
    """The reference a reply carries for ``command``."""
    return zlib.crc32(command)


def message_dtype(count: int) -> np.dtype:
    """A message of ``count`` float64 values as a numpy record: its header (``HEADER_DTYPE``), then the values."""
    return np.dtype([("header", HEADER_DTYPE), ("values", "<f8", (count,))])


def encode_rows(kind: Kind, steps: np.ndarray, base_step_ns: int, values: np.ndarray, rows: int,
                references: np.ndarray | int) -> np.ndarray:
    """Messages of one kind and shape, a row of ``values`` each, at ``steps`` (their time: step × ``base_step_ns``),
    as ``encode`` writes them: one message per row of bytes."""
    records = np.zeros(len(steps), dtype=message_dtype(values.shape[1]))
    header = records["header"]
    header["version"], header["kind"], header["rows"], header["count"] = VERSION, kind, rows, values.shape[1]
    header["step"], header["time_ns"], header["ref"] = steps, steps * base_step_ns, references
    records["values"] = values
    return records.view(np.uint8).reshape(len(steps), records.dtype.itemsize)


def command_refs(commands: np.ndarray) -> np.ndarray:
    """``command_ref`` of each command of ``commands`` (one per row of bytes, as ``encode_rows`` gives them): for
    commands of up to ``TABLED_BYTES`` bytes, CRC-32 as the affine map it is on messages of one length, one table
    lookup per byte and an exclusive or of them all (``_crc_tables``), with numpy: 0.54 → 0.1 µs per command of
    two_mass_damped, where each ``zlib.crc32`` call took a numpy row and a Python call."""
    length = commands.shape[1]
    if length > TABLED_BYTES:
        return np.fromiter(map(command_ref, commands), np.uint32, len(commands))
    of_zeros, tables = _crc_tables(length)
    return np.bitwise_xor.reduce(tables[np.arange(length), commands], axis=1, initial=of_zeros)


TABLED_BYTES = 256  # commands up to this long take their CRC-32 from tables (length × 256 × 4 bytes)


@functools.cache
def _crc_tables(length: int) -> tuple[int, np.ndarray]:
    """CRC-32 is affine over GF(2) for messages of ``length`` bytes: ``crc(m) = crc(0…0) ⊕ ⨁_p T[p, m_p]`` with
    ``T[p, v] = crc(v at p, zeros elsewhere) ⊕ crc(0…0)`` (linearity of the remainder; zlib's initial and final
    inversions are the affine part). Returns ``crc(0…0)`` and ``T`` (uint32), once per length: zlib gives the
    contribution of each bit, and ``T[p, v]`` is that of the bits of ``v`` together (linearity again), 8 zlib calls
    per byte instead of 256."""
    of_zeros = zlib.crc32(bytes(length))
    bits = np.empty((length, 8), dtype=np.uint32)
    message = bytearray(length)
    for p in range(length):
        for b in range(8):
            message[p] = 1 << b
            bits[p, b] = zlib.crc32(message) ^ of_zeros
        message[p] = 0
    has_bit = (np.arange(256)[:, None] >> np.arange(8)) & 1 == 1  # (value, bit)
    return of_zeros, np.bitwise_xor.reduce(np.where(has_bit, bits[:, None, :], np.uint32(0)), axis=2)


def decode(data: bytes, sender: str) -> Message:
    """Decode and validate one message from ``sender`` (named in every error)."""
    kind, rows, count, step, time_ns, ref = decode_header(data, sender)
    return Message(kind, step, time_ns, rows, ref,
                   np.frombuffer(data, dtype=_DTYPE[kind], count=count, offset=HEADER.size))


def decode_header(data: bytes, sender: str) -> tuple[Kind, int, int, int, int, int]:
    """Validate one message from ``sender``; return ``(kind, rows, count, step, time_ns, ref)`` of its header."""
    if len(data) < HEADER.size:
        raise ProtocolError(f"message from {sender}: {len(data)} bytes, shorter than the {HEADER.size}-byte header")
    version, kind, rows, count, step, time_ns, ref = HEADER.unpack_from(data)
    if version != VERSION:
        raise ProtocolError(f"message from {sender}: protocol version {version}, expected {VERSION}")
    kind = _KINDS.get(kind)
    if kind is None:
        raise ProtocolError(f"message from {sender}: unknown kind {HEADER.unpack_from(data)[1]}")
    expected = HEADER.size + _ITEMSIZE[kind] * count
    if len(data) != expected:
        raise ProtocolError(f"message from {sender}: {len(data)} bytes, expected {expected} for {count} values")
    if rows and (count % rows):
        raise ProtocolError(f"message from {sender}: {count} values do not fill {rows} rows")
    return kind, rows, count, step, time_ns, ref
