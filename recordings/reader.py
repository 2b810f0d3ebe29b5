"""Read a recording back: its metadata, its scene, and every message of every channel.

A recording that was cut short (the recorder was killed before it finished) is read up to its last
complete chunk; ``Recording.truncated`` then says where and why reading stopped. Every error names
the file, and the channel and message where it applies.
"""
from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from zencosim.manager.scene.load import Scene, SceneError, scene_from_text
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings import RecordingError
from zencosim.recordings.layout import (
    END_METADATA,
    FORMAT,
    FORMAT_1,
    RUN_METADATA,
    SCENE_ATTACHMENT,
    STATUS_TOPIC,
    ChannelSpec,
)
from zencosim.recordings.schema import ChannelSchema, StoredMessage, decode

MCAP_MAGIC = b"\x89MCAP0\r\n"
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

    def scene(self) -> Scene:
        """The recorded scene, loaded in this zencosim; RecordingError when it no longer loads or its digest
        differs from the recorded one."""
        try:
            scene = scene_from_text(self.scene_toml, f"{self.path}:{SCENE_ATTACHMENT}")
        except SceneError as error:
            raise RecordingError(f"{self.path}: its scene no longer loads in this zencosim "
                                 f"({self.info['zencosim']} recorded it): {error}") from None
        if scene.digest != self.info["scene_digest"]:
            raise RecordingError(f"{self.path}: the embedded scene's digest {scene.digest[:12]} differs from the "
                                 f"recorded {self.info['scene_digest'][:12]}")
        return scene

    def last_step(self) -> int:
        """The last step whose status was recorded (0 when none was)."""
        status = [m.step for m in self.channels[STATUS_TOPIC].messages] if STATUS_TOPIC in self.channels else []
        return max(status, default=0)


def _end_record(metadata: dict[str, str]) -> dict:
    return {key: (value if key in ("outcome", "path", "first_malformed", "finished") else json.loads(value))
            for key, value in metadata.items()}


def read_recording(path: str | Path) -> Recording:
    """Read a whole recording; raise :class:`RecordingError` naming the file when it is not one."""
    path = Path(path)
    try:
        handle = open(path, "rb")
    except OSError as error:
        raise RecordingError(f"cannot read recording {path}: {error.strerror}") from None
    with handle:
        if handle.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RecordingError(f"{path} is not an MCAP file (it does not start with the MCAP magic bytes)")
        handle.seek(0)
        return _read(path, handle)


def _read(path: Path, handle) -> Recording:
    info: dict[str, str] | None = None
    end = None
    scene_toml = None
    channels: dict[int, ChannelRecord] = {}
    schemas: dict[int, str] = {}
    truncated = "the file ends without an MCAP footer"
    records = StreamReader(handle, validate_crcs=True).records
    while True:
        try:
            record = next(records)
        except StopIteration:
            break
        except (McapError, EOFError, struct.error, ValueError) as error:
            truncated = f"the file is cut off or damaged after {handle.tell()} bytes ({type(error).__name__}: {error})"
            break
        if isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None:
                raise RecordingError(f"{path}: a message on channel id {record.channel_id}, which is not declared")
            try:
                channel.messages.append(decode(record.data, channel.schema))
            except ValueError as error:
                raise RecordingError(f"{path}: channel {channel.spec.topic}, message {len(channel.messages) + 1}: "
                                     f"{error}") from None
            channel.log_ns.append(record.log_time)
        elif isinstance(record, Channel) and record.id not in channels:
            try:
                spec = ChannelSpec.from_metadata(record.topic, record.metadata)
            except (KeyError, ValueError):
                raise RecordingError(f"{path}: channel {record.topic} is not a zencosim channel "
                                     "(its metadata does not name its values)") from None
            schema = None if schemas.get(record.schema_id) == FORMAT_1_SCHEMA else ChannelSchema(spec)
            if schema is not None and schemas.get(record.schema_id) != schema.name:
                raise RecordingError(f"{path}: channel {record.topic} has schema {schemas.get(record.schema_id)!r}, "
                                     f"expected {schema.name}: not a zencosim recording")
            channels[record.id] = ChannelRecord(spec, schema)
        elif isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Metadata) and record.name == RUN_METADATA:
            info = dict(record.metadata)
        elif isinstance(record, Metadata) and record.name == END_METADATA:
            end = _end_record(record.metadata)
        elif isinstance(record, Attachment) and record.name == SCENE_ATTACHMENT:
            scene_toml = record.data.decode("utf-8")
        elif isinstance(record, Footer):
            truncated = None
    if info is None:
        raise RecordingError(f"{path} is an MCAP file but not a zencosim recording (no '{RUN_METADATA}' metadata)")
    if info.get("format") not in (FORMAT, FORMAT_1):
        raise RecordingError(f"{path}: recording format {info.get('format')!r}; this zencosim reads {FORMAT} "
                             f"and {FORMAT_1} (wire protocol 2)")
    if scene_toml is None:
        raise RecordingError(f"{path}: the scene attachment '{SCENE_ATTACHMENT}' is missing")
    return Recording(path, info, end, scene_toml, {c.spec.topic: c for c in channels.values()}, truncated)


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
        "channels": {topic: {"messages": len(c.messages), "values": ", ".join(f"{n} [{u}]" for n, u in
                                                                              zip(c.spec.names, c.spec.units))}
                     for topic, c in recording.channels.items()},
    }
