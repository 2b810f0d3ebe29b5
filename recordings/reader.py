"""Read a recording back: its metadata, its scene, and every message of every channel.

The file is read by ``recordings.mcap_read``, which trusts none of its lengths and checks every CRC
MCAP offers. A recording that was cut short (the recorder was killed before it finished) is read up to
its last complete chunk; ``Recording.truncated`` then says where and why reading stopped. A recording
whose recorder finished holds an end record after its last chunk (``recordings.writer``): its SHA-256
of every byte before it, its messages per channel and its number of chunks are compared with what was
read, and every mismatch, like every failed MCAP check, is listed in ``Recording.damage``. A file
that cannot be read as a recording at all (not MCAP, no run metadata, no scene, undeclared channels,
a message that does not decode) is a :class:`RecordingError` naming the file and what is wrong.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.records import Attachment, Channel, Message, Metadata, Schema

from zencosim.manager.scene.load import Scene, SceneError, scene_from_text
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings import RecordingError
from zencosim.recordings.decoding import decode_messages
from zencosim.recordings.layout import (
    CONTENT_DIGEST,
    END_METADATA,
    FORMAT,
    FORMAT_1,
    RUN_METADATA,
    SCENE_ATTACHMENT,
    STATUS_TOPIC,
    ChannelSpec,
)
from zencosim.recordings.mcap_read import MAGIC, McapScan
from zencosim.recordings.schema import ChannelSchema, StoredMessage

DECODE_BLOCK = 8192  # messages of a channel decoded at once (recordings.decoding)
FORMAT_1_SCHEMA = "zencosim.Message"  # the one generic message of every channel of a format 1 recording


@dataclass
class ChannelRecord:
    """The messages of one channel in the order they were recorded."""

    spec: ChannelSpec
    schema: ChannelSchema | None = None  # None: the generic message of format 1
    messages: list[StoredMessage] = field(default_factory=list)
    log_ns: list[int] = field(default_factory=list)  # the log time of each message: wall clock [ns] of recording

    def table(self, kind: Kind) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps, times [ns] and values (one row per message) of the messages of ``kind``."""
        chosen = [m for m in self.messages if m.kind == kind]
        width = max((m.values.size for m in chosen), default=0)
        values = np.full((len(chosen), width), np.nan)
        for row, message in zip(values, chosen):
            row[:message.values.size] = message.values
        return (np.array([m.step for m in chosen], dtype=np.int64), np.array([m.time_ns for m in chosen], dtype=np.int64),
                values)


@dataclass
class Recording:
    path: Path
    info: dict[str, str]  # the run's ``zencosim`` metadata record
    end: dict | None  # the ``zencosim.end`` record; None when the recorder did not finish
    scene_toml: str
    channels: dict[str, ChannelRecord]
    truncated: str | None  # why reading stopped before the end of the file; None for a complete file
    damage: list[str] = field(default_factory=list)  # every check the file failed (recordings.mcap_read, end record)

    @property
    def intact(self) -> bool:
        """Read to its end and every check passed (a format 2 recording: its recorder finished)."""
        return self.truncated is None and not self.damage

    def scene(self) -> Scene:
        """The recorded scene, loaded in this zencosim; RecordingError when it no longer loads or its digest
        differs from the recorded one."""
        try:
            scene = scene_from_text(self.scene_toml, f"{self.path}:{SCENE_ATTACHMENT}")
        except SceneError as error:
            raise RecordingError(f"{self.path}: its scene no longer loads in this zencosim "
                                 f"({self.info['zencosim']} recorded it): {error}{self.damage_note()}") from None
        except (ValueError, TypeError, KeyError, AttributeError, IndexError, ArithmeticError, RecursionError) as error:
            raise RecordingError(f"{self.path}: its scene cannot be loaded ({type(error).__name__}: {error})"
                                 f"{self.damage_note()}") from None
        if scene.digest != self.info["scene_digest"]:
            raise RecordingError(f"{self.path}: the embedded scene's digest {scene.digest[:12]} differs from the "
                                 f"recorded {self.info['scene_digest'][:12]}{self.damage_note()}")
        return scene

    def damage_note(self) -> str:
        """What an error adds when a check of the file failed: the damage found (else nothing)."""
        return f"; the file is damaged: {'; '.join(self.damage)}" if self.damage else ""

    def last_step(self) -> int:
        """The last step whose status was recorded (0 when none was)."""
        status = [m.step for m in self.channels[STATUS_TOPIC].messages] if STATUS_TOPIC in self.channels else []
        return max(status, default=0)


_INFO_KEYS = ("format", "zencosim", "scene", "scene_digest", "run_id", "bus", "started", "steps", "macro_step_ns")
_END_TEXT = ("outcome", "path", "first_malformed", "finished", CONTENT_DIGEST)  # the end record's fields kept as text


def _end_record(metadata: dict[str, str]) -> dict:
    """The end record's fields (JSON but for ``_END_TEXT``); ValueError when it is not one."""
    try:
        end = {key: (value if key in _END_TEXT else json.loads(value)) for key, value in metadata.items()}
    except RecursionError:
        raise ValueError("a field nested too deeply") from None
    if not isinstance(end.get("outcome"), str):
        raise ValueError("no outcome")
    if not isinstance(end.get("channels"), dict) or not all(
            isinstance(c, dict) and all(isinstance(c.get(k), (int, type(None))) for k in ("published", "received", "lost"))
            for c in end["channels"].values()):
        raise ValueError("its channels are not what a recorder writes")
    if not all(isinstance(end.get(k), (int, type(None))) for k in ("lost", "messages")):
        raise ValueError("its counts are not numbers")
    return end


def read_recording(path: str | Path) -> Recording:
    """Read a whole recording; raise :class:`RecordingError` naming the file when it is not one."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = handle.read(len(MAGIC))
            if data == MAGIC:  # only then the rest (not the endless bytes of a device)
                data += handle.read()
    except OSError as error:
        raise RecordingError(f"cannot read recording {path}: {error.strerror}") from None
    if not data:
        raise RecordingError(f"{path} is empty (a recording cut off before its first byte)")
    if not data.startswith(MAGIC):
        if MAGIC.startswith(data):
            raise RecordingError(f"{path} is cut off after {len(data)} bytes, inside the MCAP magic bytes it starts with")
        raise RecordingError(f"{path} is not an MCAP file (it does not start with the MCAP magic bytes)")
    return _read(path, data)


def _read(path: Path, data: bytes) -> Recording:
    info: dict[str, str] | None = None
    end = None
    end_at = None  # the end record's offset
    scene_toml = None
    channels: dict[int, ChannelRecord] = {}
    schemas: dict[int, str] = {}
    scan = McapScan(data)
    damage = scan.damage
    last_chunk = 0
    pending: dict[int, list[tuple[int, bytes]]] = {}  # per channel id: (chunk offset, data) not decoded yet
    for at, record in scan.records():
        if isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None:
                raise RecordingError(f"{path}: a message on channel id {record.channel_id}, which is not declared")
            waiting = pending.setdefault(record.channel_id, [])
            waiting.append((at, record.data))
            if len(waiting) == DECODE_BLOCK:
                _decode_pending(path, channel, waiting)
            channel.log_ns.append(record.log_time)
            last_chunk = at
        elif isinstance(record, Channel) and record.id not in channels:
            spec = _channel_spec(path, record)
            if any(c.spec.topic == spec.topic for c in channels.values()):
                raise RecordingError(f"{path}: channel {spec.topic} is declared twice")
            schema = None if schemas.get(record.schema_id) == FORMAT_1_SCHEMA else ChannelSchema(spec)
            if schema is not None and schemas.get(record.schema_id) != schema.name:
                raise RecordingError(f"{path}: channel {record.topic} has schema {schemas.get(record.schema_id)!r}, "
                                     f"expected {schema.name}: not a zencosim recording")
            channels[record.id] = ChannelRecord(spec, schema)
        elif isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Metadata) and record.name == RUN_METADATA and info is None:
            info = dict(record.metadata)
        elif isinstance(record, Metadata) and record.name == END_METADATA:
            end_at = at
            try:
                end = _end_record(record.metadata)
            except ValueError as error:
                damage.append(f"its end record cannot be read ({error})")
        elif isinstance(record, Attachment) and record.name == SCENE_ATTACHMENT and scene_toml is None:
            try:
                scene_toml = record.data.decode("utf-8")
            except UnicodeDecodeError as error:
                raise RecordingError(f"{path}: its scene attachment is not UTF-8 text ({error})") from None
    for channel_id, waiting in pending.items():
        _decode_pending(path, channels[channel_id], waiting)
    if info is None:
        if scan.stopped:
            raise RecordingError(f"{path} is a cut-off or damaged recording: {scan.stopped}, before its run metadata "
                                 f"(the '{RUN_METADATA}' record); there is nothing to read")
        raise RecordingError(f"{path} is an MCAP file but not a zencosim recording (no '{RUN_METADATA}' metadata)")
    if info.get("format") not in (FORMAT, FORMAT_1):
        raise RecordingError(f"{path}: recording format {info.get('format')!r}; this zencosim reads {FORMAT} "
                             f"and {FORMAT_1} (wire protocol 2)")
    _check_info(path, info)
    if scene_toml is None:
        raise RecordingError(f"{path}: the scene attachment '{SCENE_ATTACHMENT}' is missing"
                             + (f" ({scan.stopped})" if scan.stopped else ""))
    by_topic = {c.spec.topic: c for c in channels.values()}
    if info["format"] == FORMAT and end_at is not None:
        _check_end(data, end_at, last_chunk, end, by_topic, len(scan.chunk_offsets), damage)
        if scan.crcs is not None and 0 in scan.crcs:
            damage.append("its data section or its summary has no CRC (a recorder writes both)")
    elif info["format"] == FORMAT and scan.stopped is None:
        damage.append("it has no end record although its footer was written")
    return Recording(path, info, end, scene_toml, by_topic, scan.stopped, damage)


def _decode_pending(path: Path, channel: ChannelRecord, waiting: list[tuple[int, bytes]]) -> None:
    """Decode a channel's messages read so far (``recordings.decoding``, a block at a time) and empty ``waiting``."""
    for number, (message, (at, _)) in enumerate(zip(decode_messages([data for _, data in waiting], channel.schema),
                                                    waiting), start=len(channel.messages) + 1):
        if isinstance(message, ValueError):
            raise RecordingError(f"{path}: channel {channel.spec.topic}, message {number} (in the chunk at byte {at}): "
                                 f"{message}")
        channel.messages.append(message)
    waiting.clear()


def _channel_spec(path: Path, record: Channel) -> ChannelSpec:
    try:
        spec = ChannelSpec.from_metadata(record.topic, record.metadata)
    except (KeyError, ValueError, TypeError, RecursionError):
        spec = None
    if spec is None or not all(isinstance(name, str) for name in spec.names + spec.units + spec.measured) \
            or len(spec.names) != len(spec.units) or spec.role not in ("inputs", "outputs", "status"):
        raise RecordingError(f"{path}: channel {record.topic} is not a zencosim channel "
                             "(its metadata does not name its values)")
    return spec


def _check_info(path: Path, info: dict[str, str]) -> None:
    """RecordingError unless the run metadata has every field a recording's reader uses."""
    missing = [key for key in _INFO_KEYS if key not in info]
    if missing:
        raise RecordingError(f"{path}: its run metadata has no {', '.join(missing)}")
    for key in ("steps", "macro_step_ns"):
        if not info[key].isdigit() or len(info[key]) > 19:
            raise RecordingError(f"{path}: its run metadata's {key} is {info[key][:40]!r}, not a count")


def _check_end(data: bytes, end_at: int, last_chunk: int, end: dict | None, channels: dict[str, ChannelRecord],
               chunks: int, damage: list[str]) -> None:
    """Compare the end record with what the file holds before it (``recordings.writer``)."""
    if last_chunk > end_at:
        damage.append(f"a chunk at byte {last_chunk} comes after the end record (at byte {end_at})")
    if end is None:
        return
    digest = end.get(CONTENT_DIGEST)
    if digest is None:
        damage.append("its end record holds no digest of the file (a format 2 file written before end records held one, or damaged): "
                      "its metadata and scene cannot be checked")
    elif hashlib.sha256(memoryview(data)[:end_at]).hexdigest() != digest:
        damage.append(f"the SHA-256 of its {end_at} bytes before the end record differs from the digest the record "
                      "holds: something before it (metadata, scene, schemas, channels or chunks) was changed")
    recorded = end.get("recorded")
    held = {topic: len(c.messages) for topic, c in channels.items()}
    if recorded != held:
        damage.append(f"its end record counts the messages per channel as {recorded}, the file holds {held}")
    if end.get("chunks") != chunks:
        damage.append(f"its end record counts {end.get('chunks')} chunks, the file holds {chunks}")


def describe(recording: Recording) -> dict:
    """What ``zencosim inspect`` shows: run, scene, duration, channels with message counts, losses."""
    info, end = recording.info, recording.end
    last = recording.last_step()
    return {
        "file": str(recording.path),
        "scene": info["scene"], "run_id": info["run_id"], "bus": info["bus"], "host": info.get("host"),
        "zencosim": info["zencosim"], "started": info["started"],
        "steps": f"{last} of {info['steps']}",
        "duration_s": last * int(info["macro_step_ns"]) * 1e-9,
        "outcome": end["outcome"] if end else "unknown: the recorder did not finish",
        "lost": (end["lost"] if end else None),
        "complete": recording.truncated is None,
        "truncated": recording.truncated,
        "damage": list(recording.damage),
        "channels": {topic: {"messages": len(c.messages), "values": ", ".join(f"{n} [{u}]" for n, u in
                                                                              zip(c.spec.names, c.spec.units))}
                     for topic, c in recording.channels.items()},
    }
