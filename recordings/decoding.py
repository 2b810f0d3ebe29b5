"""Decode a channel's messages a block at a time, with numpy, as ``recordings.encoding`` wrote them.

The recorder writes every message of one (channel, kind, rows, count) layout with the same bytes in the same
places (``encoding.body_pieces``): only the step, time, simulated time, reference and values differ. So the
messages of a block that have one length are stacked into a byte matrix; those whose constant bytes are the
layout's (one comparison over the whole matrix) are decoded by slicing its columns, and every other one (an
ERROR, a message another writer encoded, a damaged one) by the generic decoder, ``schema.decode``, which
accepts any valid protobuf encoding and names what is wrong. A layout is used only once it reads the first
message of its block exactly as the generic decoder does. Both give the same ``StoredMessage``, bit for bit
(tests/recordings/test_decoding.py).
"""
from __future__ import annotations

import numpy as np

from zencosim.recordings.encoding import PAYLOAD_AT, REF_AT, STEP_AT, TIME_AT, body_pieces
from zencosim.recordings.schema import ChannelSchema, StoredMessage, decode


class _Layout:
    """Where one layout's constant bytes, header fields and values lie in a message body."""

    def __init__(self, schema: ChannelSchema, kind: int, rows: int, count: int) -> None:
        self.kind, self.rows = kind, rows
        constant_at, constant, values_at = [], bytearray(), [0] * count
        position = 0
        self.fields: dict[int, int] = {}  # variable piece → its position in the body
        for piece in body_pieces(schema, kind, rows, count):
            if isinstance(piece, bytes):
                constant_at += range(position, position + len(piece))
                constant += piece
                position += len(piece)
                continue
            start, length = piece
            if start >= PAYLOAD_AT:  # one value, or a packed run of them (a message the named fields do not describe)
                first = (start - PAYLOAD_AT) // 8
                for j in range(length // 8):
                    values_at[first + j] = position + 8 * j
            else:
                self.fields[start] = position
            position += length
        self.size = position
        self.constant_at = np.array(constant_at)
        self.constant = np.frombuffer(bytes(constant), dtype=np.uint8)
        self.values = (np.array(values_at)[:, None] + np.arange(8)).ravel()  # the bytes of value j at 8j … 8j + 7

    def matches(self, block: np.ndarray) -> np.ndarray:
        """Which rows of ``block`` (messages of this layout's size, one per row) have its constant bytes."""
        return np.all(block[:, self.constant_at] == self.constant, axis=1)

    def decode(self, block: np.ndarray) -> list[StoredMessage]:
        def field(start: int, size: int, dtype: str) -> list[int]:
            at = self.fields[start]
            return np.ascontiguousarray(block[:, at:at + size]).view(dtype)[:, 0].tolist()

        values = np.ascontiguousarray(block[:, self.values]).view("<f8")
        return [StoredMessage(step, time_ns, self.kind, self.rows, row, "", ref)
                for step, time_ns, ref, row in zip(field(STEP_AT, 8, "<i8"), field(TIME_AT, 8, "<i8"),
                                                    field(REF_AT, 4, "<u4"), values)]


def decode_messages(datas: list[bytes], schema: ChannelSchema | None) -> list[StoredMessage | ValueError]:
    """The messages ``datas`` of one channel, decoded, in order; a message that does not decode is the
    ``ValueError`` the generic decoder raised (the caller names it with its place in the file)."""
    decoded: list[StoredMessage | ValueError | None] = [None] * len(datas)
    by_size: dict[int, list[int]] = {}
    for i, data in enumerate(datas):
        by_size.setdefault(len(data), []).append(i)
    for size, indices in by_size.items():
        indices = np.array(indices)
        placed = np.zeros(len(indices), dtype=bool)  # the messages the layout decodes; the generic decoder the rest
        first = _generic(datas[indices[0]], schema) if schema is not None and size and len(indices) > 1 else None
        if isinstance(first, StoredMessage) and first.values.size and not first.text:
            layout = _Layout(schema, first.kind, first.rows, first.values.size)
            if layout.size == size:
                block = np.frombuffer(b"".join(datas[i] for i in indices), dtype=np.uint8).reshape(len(indices), size)
                placed = layout.matches(block)
                # a layout is used only once it reads its own first message as the generic decoder does
                if placed[0] and same_message(layout.decode(block[:1])[0], first):
                    for i, message in zip(indices[placed], layout.decode(block[placed])):
                        decoded[i] = message
                else:
                    placed[:] = False
        for i in indices[~placed]:
            decoded[i] = _generic(datas[i], schema)
    return decoded


def same_message(a: StoredMessage, b: StoredMessage) -> bool:
    """Two decoded messages alike to the bit (their values' bytes compared, so NaN payloads too)."""
    return ((a.step, a.time_ns, a.kind, a.rows, a.text, a.ref) == (b.step, b.time_ns, b.kind, b.rows, b.text, b.ref)
            and a.values.tobytes() == b.values.tobytes())


def _generic(data: bytes, schema: ChannelSchema | None) -> StoredMessage | ValueError:
    try:
        return decode(data, schema)
    except ValueError as error:
        return error
