"""The recorder process: writes one run to MCAP on its own core, off the stepping loop's critical path.

    python -m recordings.recorder_process     (started by recordings.recorder.Recorder, never by hand)

Its standard input carries frames (``FRAME``: kind u16, length u32, wall-clock time i64 [ns], then
``length`` bytes). ``CONTROL`` frames hold JSON: the first, START, says where to write, the metadata,
the scene and the channels; the last, END, gives the outcome of the run and what the manager's tap
handed over per channel (the end record compares it with what was written). ``BATCH`` frames hold
wire messages: ``BATCH_HEAD`` (messages n, of which m are statuses, and the statuses' bytes), n channel
indices (u8) in the run's order, m wall-clock times (i64, one per status message: when its step completed,
the log time of it and of the messages after it), the m statuses, all of one size (the tap takes them from
the status log: ``manager.wire.status``), and then the list of the n - m other messages as ``marshal`` writes
it — one C call for the tap, a fifth of the time of joining the messages and listing their sizes (the two
processes run the same Python, whose marshal format this is); :func:`split_batch` gives them in the run's
order. ``STEPS`` frames hold a block of a direct (in-process) run's exchanges as arrays, and ``ROWS`` frames a
generated loop's rows, from which :func:`frame_messages` builds the same messages (``recordings.steps_frame``,
``recordings.rows_frame``); ``PENDING`` frames the requests a direct run took since its last block, recorded only
when no block follows them (``steps_frame.pending_steps``). The same input serves both buses: on
the Zenoh bus the manager's replica, which follows the run, is the one tapped.

SIGINT is ignored (a Ctrl-C reaches the whole process group; the manager then sends END). SIGTERM
(also sent by the kernel when the manager dies) and an end of input without END finish the file with
what has arrived, the frames still in the pipe among it, and the last PENDING frames' requests (``record_pipe``).
Standard output gets one JSON line when ready and one when finished; a write that fails (a full disk) ends it with
status 1 after a line that says why (``failed``).
"""
from __future__ import annotations

import json
import marshal
import os
import select
import signal
import struct
import sys
from typing import NamedTuple

import numpy as np

from zencosim.manager.bus.children import end_with_parent
from zencosim.manager.bus.signals import SignalNote
from zencosim.recordings import RecordingError
from zencosim.recordings.layout import ChannelSpec, status_index
from zencosim.recordings.rows_frame import rows_messages
from zencosim.recordings.steps_frame import pending_steps, steps_messages
from zencosim.recordings.writer import RecordingWriter

FRAME = struct.Struct("<HIq")
CONTROL, BATCH, STEPS, ROWS, PENDING = 0xFFFF, 0xFFFE, 0xFFFD, 0xFFFC, 0xFFFB
BATCH_HEAD = struct.Struct("<III")
IDLE_S = 0.1  # the pipe reader lets the writer flush after this long without input
DRAIN_BYTES = 4 << 20  # after SIGTERM at most this much more is read: what the pipe holds (1 MiB asked) and more
NO_END = "the manager ended without closing the recording"


class FrameReader:
    """Frames from a file descriptor; ``next`` returns None at end of input, or on SIGTERM once nothing is
    pending; ``idle`` is called while no input arrives."""

    def __init__(self, fd: int, stop: SignalNote, idle=lambda: None) -> None:
        self.fd = fd
        self.stop = stop
        self.idle = idle
        self.buffer = bytearray()
        self.at = 0
        self.drained = 0  # bytes read after SIGTERM

    def _fill(self) -> bool:
        """Read what arrived into the buffer; False at the end of input. After SIGTERM only what the pipe holds
        already is read, at most ``DRAIN_BYTES``: a manager that died (the kernel sends SIGTERM) wrote every frame
        it handed over into the pipe, and they are recorded, not left in it; one that still runs is not waited for."""
        while True:
            stopped = self.stop.received is not None
            if stopped and self.drained >= DRAIN_BYTES:
                return False
            if not select.select([self.fd], [], [], 0 if stopped else IDLE_S)[0]:
                if stopped:
                    return False
                self.idle()
                continue
            data = os.read(self.fd, 1 << 20)
            if not data:
                return False
            if stopped:
                self.drained += len(data)
            del self.buffer[:self.at]
            self.at = 0
            self.buffer += data
            return True

    def next(self) -> tuple[int, bytes, int] | None:
        """(kind, payload, wall-clock ns) of the next frame."""
        while True:
            available = len(self.buffer) - self.at
            if available >= FRAME.size:
                channel, length, publish_ns = FRAME.unpack_from(self.buffer, self.at)
                if available >= FRAME.size + length:
                    start = self.at + FRAME.size
                    self.at = start + length
                    return channel, bytes(self.buffer[start:self.at]), publish_ns
            if not self._fill():
                return None


class Batch(NamedTuple):
    """The messages of a BATCH frame (:func:`split_batch`), in the run's order, one after the other."""

    channels: np.ndarray  # the channel index of each
    sizes: np.ndarray  # [bytes]
    stamps: np.ndarray  # the wall-clock time [ns] of each status (and of the messages after it)
    messages: bytes


def split_batch(batch: bytes, status: int) -> Batch:
    """The messages of a BATCH frame, put back in the run's order (the statuses among the others) as they are
    joined; ``status``: the index of the status channel. A frame that does not hold what its head says raises
    ValueError."""
    n, m, statuses_bytes = BATCH_HEAD.unpack_from(batch)
    at = BATCH_HEAD.size
    channels = np.frombuffer(batch, dtype=np.uint8, count=n, offset=at)
    stamps = np.frombuffer(batch, dtype="<i8", count=m, offset=at + n)
    at += n + 8 * m
    statuses = batch[at:at + statuses_bytes]
    try:
        others = marshal.loads(memoryview(batch)[at + statuses_bytes:])
    except (EOFError, ValueError, TypeError):
        others = None
    is_status = channels == status
    if (len(statuses) != statuses_bytes or (statuses_bytes % m if m else statuses_bytes) or type(others) is not list
            or len(others) != n - m or not all(type(message) is bytes for message in others)
            or int(np.count_nonzero(is_status)) != m):
        raise ValueError(f"a batch frame of {n} messages ({m} statuses, {statuses_bytes} bytes) that does not "
                         f"hold them")
    size = statuses_bytes // m if m else 0
    statuses_in_order = (statuses[start:start + size] for start in range(0, statuses_bytes, size or 1))
    others_in_order = iter(others)
    ordered = [next(statuses_in_order if at_status else others_in_order) for at_status in is_status.tolist()]
    return Batch(channels, np.fromiter(map(len, ordered), dtype=np.int64, count=n), stamps, b"".join(ordered))


def channel_index(specs: list[ChannelSpec]) -> dict[tuple[str, str], int]:
    """The index of each channel by (source, channel): ``("S1", "y")``, ``("manager", "status")``."""
    return {tuple(spec.topic.split("/")): i for i, spec in enumerate(specs)}


def frame_messages(kind: int, data: bytes, index: dict[tuple[str, str], int], status: int) -> Batch:
    """The messages of a BATCH, STEPS or ROWS frame in the run's order; ValueError for one that does not hold them."""
    if kind == STEPS:
        return Batch(*steps_messages(data, index, status))
    if kind == ROWS:
        return Batch(*rows_messages(data, index, status))
    return split_batch(data, status)


def record_pipe(frames: FrameReader, writer: RecordingWriter) -> tuple[str, dict | None]:
    """Record the wire messages of a run until END; return (outcome, published). PENDING frames are kept until a
    frame that holds their requests follows them, and recorded when none does: the run's process ended (a model
    ended it) before it handed them over as a block."""
    status, index = status_index(writer.channels), channel_index(writer.channels)
    pending: list[bytes] = []
    while (frame := frames.next()) is not None:
        kind, data, _ = frame
        if kind == CONTROL:
            end = json.loads(data)
            return end["outcome"], end["published"]
        if kind == PENDING:
            pending.append(data)
            continue
        pending.clear()
        writer.write(*frame_messages(kind, data, index, status))
    if pending and (steps := pending_steps(pending)) is not None:
        writer.write(*frame_messages(STEPS, steps, index, status))
    return ("stopped by SIGTERM: " if frames.stop.received else "") + NO_END, None


def announce(event: dict) -> None:
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def observe() -> tuple[FrameReader, dict | None]:
    """An observer process's start (the recorder's, the live view's): SIGINT ignored (a Ctrl-C reaches the
    whole process group; the manager then sends END), SIGTERM noted; the frames of standard input and
    the START frame's JSON (None, said on standard error, when the first frame is not one)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    frames = FrameReader(sys.stdin.fileno(), SignalNote(signal.SIGTERM))
    end_with_parent()  # SIGTERM, noted above, when the manager dies
    first = frames.next()
    if first is None or first[0] != CONTROL:
        print(f"{sys.argv[0]}: expected a START frame on standard input", file=sys.stderr)
        return frames, None
    return frames, json.loads(first[1])


def failed(error: OSError) -> int:
    """A write to the file failed (a full disk, an I/O error): the reason goes on standard output, where the
    manager reads why the recorder is gone (``recordings.recorder``), and the process exits with status 1."""
    announce({"event": "failed", "reason": f"writing the file failed: {error.strerror or error}"})
    return 1


def main() -> int:
    frames, start = observe()
    if start is None:
        return 2
    try:
        writer = RecordingWriter(start["path"], start["metadata"], start["scene_toml"],
                                 [ChannelSpec.from_metadata(c["topic"], c["metadata"]) for c in start["channels"]])
    except RecordingError as error:  # a path it cannot open
        announce({"event": "error", "reason": str(error)})
        return 2
    except OSError as error:  # the first records did not fit
        return failed(error)
    frames.idle = writer.flush_if_due
    announce({"event": "ready"})
    try:
        outcome, published = record_pipe(frames, writer)
        end = writer.finish(outcome, published)
    except OSError as error:
        return failed(error)
    announce({"event": "finished", **end})
    return 0


if __name__ == "__main__":
    sys.exit(main())
