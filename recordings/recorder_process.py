"""The recorder process: writes one run to MCAP on its own core, off the stepping loop's critical path.

    python -m recordings.recorder_process     (started by recordings.recorder.Recorder, never by hand)

Its standard input carries frames (``FRAME``: kind u16, length u32, wall-clock time i64 [ns], then
``length`` bytes). ``CONTROL`` frames hold JSON: the first, START, says where to write, the metadata,
the scene and the channels, and for a Zenoh run the run id and the endpoint to listen on; the last,
END, gives the outcome of the run and what the manager published per channel. ``BATCH`` frames (the
in-process bus) hold wire messages: ``BATCH_HEAD`` (messages n, stamps m), n channel indices (u8),
n message sizes (u32), m wall-clock times (i64, one per status message: it and the messages after it
were handed over then), and the n messages one after the other.

On the Zenoh bus the recorder listens on its endpoint (the manager and every subsystem connect to
it), subscribes to ``zencosim/<run-id>/**`` (keys that are not channels, such as the start signal,
are passed over) with a FIFO handler (a full queue blocks Zenoh, and the publishers'
``CongestionControl.BLOCK`` turns that into backpressure rather than drops; a recorder frozen for
longer than Zenoh's lease, 10 s, is disconnected instead, see docs/recording.md), and only
then declares its liveliness token, which the manager and the subsystems wait for. After END it
waits until it has received what the manager published, or until nothing arrives for
``QUIET_S``, then finishes the file; the end record counts what was lost.

SIGINT is ignored (a Ctrl-C reaches the whole process group; the manager then sends END). SIGTERM
(also sent by the kernel when the manager dies) and an end of input without END finish the file with
what has arrived once nothing more has for ``LINGER_S``. Standard output gets one JSON line when
ready and one when finished.
"""
from __future__ import annotations

import json
import os
import select
import signal
import struct
import sys
import threading
import time
from array import array

from recordings import RecordingError
from recordings.layout import ChannelSpec
from recordings.writer import RecordingWriter

FRAME = struct.Struct("<HIq")
CONTROL, BATCH = 0xFFFF, 0xFFFE
BATCH_HEAD = struct.Struct("<II")
FIFO_CAPACITY = 2048  # samples queued between Zenoh and the writer before Zenoh blocks
QUIET_S = 2.0  # after END, give up waiting for missing messages once nothing arrived for this long
LINGER_S = 0.3  # after SIGTERM or the end of input without END, finish once nothing arrived for this long
POLL_S = 0.0005  # sleep when the Zenoh queue is empty
IDLE_S = 0.1  # the pipe reader lets the writer flush after this long without input
NO_END = "the manager ended without closing the recording"


class FrameReader:
    """Frames from a file descriptor; ``next`` returns None at end of input, or on SIGTERM once nothing is
    pending; ``idle`` is called while no input arrives."""

    def __init__(self, fd: int, stop: threading.Event, idle=lambda: None) -> None:
        self.fd = fd
        self.stop = stop
        self.idle = idle
        self.buffer = bytearray()
        self.at = 0

    def _fill(self) -> bool:
        while not self.stop.is_set():
            if not select.select([self.fd], [], [], IDLE_S)[0]:
                self.idle()
                continue
            data = os.read(self.fd, 1 << 20)
            if not data:
                return False
            del self.buffer[:self.at]
            self.at = 0
            self.buffer += data
            return True
        return False

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


def record_batch(writer: RecordingWriter, batch: bytes, publish_ns: int, status: int) -> int:
    """Write the messages of one BATCH frame (``status``: the status channel's index); return the wall
    clock of its last stamp, which also stamps the first messages of the next batch."""
    n, m = BATCH_HEAD.unpack_from(batch)
    at = BATCH_HEAD.size
    channels = batch[at:at + n]
    sizes = array("I", batch[at + n:at + 5 * n])
    stamps = array("q", batch[at + 5 * n:at + 5 * n + 8 * m])
    at += 5 * n + 8 * m
    stamped = 0
    for channel, size in zip(channels, sizes):
        if channel == status:
            publish_ns = stamps[stamped]
            stamped += 1
        writer.write(channel, batch[at:at + size], publish_ns)
        at += size
    return publish_ns


def record_pipe(frames: FrameReader, writer: RecordingWriter) -> tuple[str, dict | None]:
    """Record the wire messages of the in-process bus until END; return (outcome, published)."""
    status = next(i for i, spec in enumerate(writer.channels) if spec.role == "status")
    stamp = time.time_ns()
    while (frame := frames.next()) is not None:
        kind, data, _ = frame
        if kind == CONTROL:
            end = json.loads(data)
            return end["outcome"], end["published"]
        stamp = record_batch(writer, data, stamp, status)
    return ("stopped by SIGTERM: " if frames.stop.is_set() else "") + NO_END, None


def record_zenoh(frames: FrameReader, writer: RecordingWriter, zenoh_start: dict) -> tuple[str, dict | None]:
    """Record every sample under the run's key until END (and what it announces) has arrived."""
    import zenoh

    from manager.zenoh_session import RECORDER, ZenohOptions, key, peer_config

    topics = {spec.topic: index for index, spec in enumerate(writer.channels)}
    run_id = zenoh_start["run_id"]
    prefix = len(key(run_id, ""))
    end: list[tuple[str, dict | None]] = []  # (outcome, published) once END arrived or the input ended

    def control() -> None:
        frame = frames.next()
        if frame is not None:
            message = json.loads(frame[1])
            end.append((message["outcome"], message["published"]))
        elif not frames.stop.is_set():
            end.append((NO_END, None))

    options = ZenohOptions(lowlatency=zenoh_start["lowlatency"])
    with zenoh.open(peer_config(listen=[zenoh_start["endpoint"]], options=options)) as session:
        samples = session.declare_subscriber(key(run_id, "**"), zenoh.handlers.FifoChannel(FIFO_CAPACITY))
        token = session.liveliness().declare_token(key(run_id, RECORDER, "alive"))
        threading.Thread(target=control, daemon=True).start()
        _announce({"event": "ready"})
        last_arrival = time.monotonic()
        while True:
            sample = samples.try_recv()
            if sample is not None:
                index = topics.get(str(sample.key_expr)[prefix:])
                if index is not None:
                    writer.write(index, sample.payload.to_bytes(), time.time_ns())
                last_arrival = time.monotonic()
                continue
            idle_s = time.monotonic() - last_arrival
            if frames.stop.is_set() or (end and end[0][1] is None):
                if idle_s > LINGER_S:  # the manager is gone: what was in flight has arrived
                    break
            elif end:
                published = end[0][1]
                if idle_s > QUIET_S or all(writer.received[topics[t]] >= n for t, n in published.items() if t in topics):
                    break
            writer.flush_if_due()
            time.sleep(POLL_S)
        token.undeclare()
        samples.undeclare()
    return end[0] if end else (f"stopped by SIGTERM: {NO_END}", None)


def _announce(event: dict) -> None:
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def main() -> int:
    stop = threading.Event()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    frames = FrameReader(sys.stdin.fileno(), stop)
    first = frames.next()
    if first is None or first[0] != CONTROL:
        print("recorder: expected a START frame on standard input", file=sys.stderr)
        return 2
    start = json.loads(first[1])
    try:
        writer = RecordingWriter(start["path"], start["metadata"], start["scene_toml"],
                                 [ChannelSpec.from_metadata(c["topic"], c["metadata"]) for c in start["channels"]])
    except RecordingError as error:
        _announce({"event": "error", "reason": str(error)})
        return 2
    if start.get("zenoh"):
        outcome, published = record_zenoh(frames, writer, start["zenoh"])
    else:
        frames.idle = writer.flush_if_due
        _announce({"event": "ready"})
        outcome, published = record_pipe(frames, writer)
    _announce({"event": "finished", **writer.finish(outcome, published)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
