"""Damage a recording's bytes the ways a disk, a copy or a person does: bit flips, truncation, two chunks
swapped, a byte range zeroed, and a flip inside one of the records outside the chunks (metadata, scene,
schemas, channels, end record, summary, footer); a crafted recording whose scene claims a longer
run than it holds (``claiming_duration``), and one that holds no message (``emptied``). Used by the fuzz test
(tests/recordings/test_damaged_recordings.py) and by ``benchmarks/corrupt_recordings.py``; each function takes the
intact bytes and returns a damaged copy.
"""
from __future__ import annotations

import struct
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"
CHUNK = 0x06


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of every top-level record of an intact MCAP file, in order."""
    found, at = [], len(MAGIC)
    while at + 9 <= len(data) - len(MAGIC):
        opcode, length = struct.unpack_from("<BQ", data, at)
        found.append((opcode, at, at + 9 + length))
        at += 9 + length
    return found


def flip_bits(data: bytes, positions: list[int]) -> bytes:
    """``data`` with bit ``p % 8`` of byte ``p // 8 % len(data)`` flipped, for every p."""
    out = bytearray(data)
    for p in positions:
        out[p // 8 % len(out)] ^= 1 << (p % 8)
    return bytes(out)


def truncate(data: bytes, length: int) -> bytes:
    return data[:length % len(data)]


def zero_range(data: bytes, start: int, length: int) -> bytes:
    start %= len(data)
    end = min(start + length, len(data))
    return data[:start] + bytes(end - start) + data[end:]


def swap_chunks(data: bytes, first: int, second: int) -> bytes:
    """Chunks ``first`` and ``second`` (modulo their number) swapped with their message indexes, each with
    the records that follow it up to the next chunk; the data unchanged when there are fewer than two."""
    spans = _chunk_spans(data)
    if len(spans) < 2:
        return data
    i, j = sorted((first % len(spans), second % len(spans)))
    if i == j:
        j = (i + 1) % len(spans)
        i, j = sorted((i, j))
    (a0, a1), (b0, b1) = spans[i], spans[j]
    return data[:a0] + data[b0:b1] + data[a1:b0] + data[a0:a1] + data[b1:]


def flip_in_record(data: bytes, which: int, bit: int) -> bytes:
    """One bit flipped inside top-level record ``which`` (modulo their number) among those that are not chunks
    or message indexes."""
    chosen = [(start, end) for opcode, start, end in records(data) if opcode not in (CHUNK, 0x07)]
    start, end = chosen[which % len(chosen)]
    return flip_bits(data, [start * 8 + bit % ((end - start) * 8)])


def _chunk_spans(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each chunk with the message indexes after it."""
    spans: list[list[int]] = []
    for opcode, start, end in records(data):
        if opcode == CHUNK:
            spans.append([start, end])
        elif opcode == 0x07 and spans and spans[-1][1] == start:
            spans[-1][1] = end
    return [(a, b) for a, b in spans]


KINDS = ("flip", "flips", "truncate", "swap", "zero", "record")


def corrupt(data: bytes, kind: str, a: int, b: int) -> bytes:
    """A damaged copy of ``data``: ``kind`` one of ``KINDS``, ``a`` and ``b`` its two parameters (any
    non-negative integers; each kind takes them modulo what it needs)."""
    if kind == "flip":
        return flip_bits(data, [a])
    if kind == "flips":
        return flip_bits(data, [a + k * (b % 997 + 1) for k in range(2 + b % 7)])
    if kind == "truncate":
        return truncate(data, a)
    if kind == "swap":
        return swap_chunks(data, a, b)
    if kind == "zero":
        return zero_range(data, a, 1 + b % 4096)
    if kind == "record":
        return flip_in_record(data, a, b)
    raise ValueError(kind)


def claiming_duration(recording_path: Path, out: Path, duration_s: float) -> Path:
    """A well-formed recording at ``out`` with the metadata and channels of ``recording_path`` (recorded with
    ``manager.duration = 0.01``) and no messages, whose embedded scene claims ``duration_s`` (its digest
    updated to match): an attacker's small file that asks a re-run of a huge run."""
    from zencosim.manager.scene.load import scene_from_text
    from zencosim.recordings.reader import read_recording
    from zencosim.recordings.writer import RecordingWriter
    recording = read_recording(recording_path)
    toml = recording.scene_toml.replace("duration = 0.01", f"duration = {duration_s!r}")
    assert toml != recording.scene_toml, "the scene text has no 'duration = 0.01'"
    scene = scene_from_text(toml, "crafted")
    writer = RecordingWriter(out, {**recording.info, "scene_digest": scene.digest}, toml,
                             [c.spec for c in recording.channels.values()])
    writer.finish("completed", {})
    return out


def emptied(recording_path: Path, out: Path, outcome: str) -> Path:
    """A well-formed, intact recording at ``out`` with the metadata, scene and channels of ``recording_path``,
    no messages, and an end record saying the run ended ``outcome`` (completed, failed, interrupted)."""
    from zencosim.recordings.reader import read_recording
    from zencosim.recordings.writer import RecordingWriter
    recording = read_recording(recording_path)
    writer = RecordingWriter(out, recording.info, recording.scene_toml, [c.spec for c in recording.channels.values()])
    writer.finish(outcome, {})
    return out
