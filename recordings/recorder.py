"""The manager's handle on a recorder process (recordings.recorder_process).

``start`` spawns the process (it dies with the manager), sends it the run's description and waits
until it is ready; ``tap`` (on the manager's replica, in process or following a Zenoh run) hands it
every message through a pipe — the tap only appends the message and its channel to two lists, and
every ``BATCH_MESSAGES`` messages (after every step of a real-time run) they go down the pipe as one
frame, so validation, encoding and compression run in the other process, on the other core. A full
pipe blocks the tap: backpressure, never a drop. ``finish`` sends the outcome and what the tap
handed over and returns the recorder's end record (outcome, per-channel published / received / lost).
"""
from __future__ import annotations

import contextlib
import fcntl
import json
import select
import signal
import subprocess
import tempfile
import threading
from array import array
from collections import Counter
from pathlib import Path
from time import time_ns

import tomli_w

from zencosim.manager.bus.children import start_child
from zencosim.manager.bus.signals import SignalNote
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scene.load import Scene
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings import RecordingError
from zencosim.recordings.layout import STATUS_TOPIC, ChannelSpec, channel_specs, run_metadata
from zencosim.recordings.recorder_process import BATCH, BATCH_HEAD, CONTROL, FRAME

READY_TIMEOUT_S = 30.0  # the recorder process must be ready within this time
FINISH_TIMEOUT_S = 120.0  # and have written the file within this time after END
PIPE_BYTES = 1 << 20  # pipe capacity asked of the kernel: room for bursts before the tap blocks
BATCH_MESSAGES = 2048  # the tap hands messages over in batches of about this many (at a status message)
F_SETPIPE_SZ = 1031  # Linux fcntl


@contextlib.contextmanager
def _interrupts_deferred():
    """SIGINT and SIGTERM that arrive inside the block act when it ends.

    Python runs signal handlers, and raises their KeyboardInterrupt, only in the main thread; so only
    there is anything deferred (a recorded Zenoh run flushes from the follower thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    arrived = SignalNote(*previous)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if arrived.signum is not None:
            handler = previous[arrived.signum]
            if callable(handler):
                handler(arrived.signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(arrived.signum)


class Recorder:
    """Records one run to ``path``: create it, pass it to ``manager.run.execute``, read ``result``."""

    def __init__(self, path: str | Path, host_info: bool = False) -> None:
        self.path = check_output_file(path, "recording")
        self.host_info = host_info  # record the host's name and the scene's path (layout.run_metadata)
        self.result: dict | None = None
        self._process: subprocess.Popen | None = None
        self._log = tempfile.TemporaryFile()
        self._index: dict[tuple[str, str], int] = {}  # (source, channel) → channel index
        self._topics: list[str] = []
        self._status = -1  # index of the status channel
        self._channels = bytearray()  # the batch being tapped: channel index of each message
        self._messages: list[bytes] = []  # and the messages
        self._stamps: list[int] = []  # wall clock [ns] at each status message of the batch
        self._tapped: Counter[int] = Counter()  # messages handed over, per channel index
        self._paced = False  # a real-time run: the tap hands each step over at once

    def start(self, scene: Scene, plan: Plan, status: StatusReport, bus: str, run_id: str, realtime: bool) -> None:
        """Start the recorder process and wait until it is ready."""
        specs = channel_specs(plan, status)
        self._declare(specs, realtime)
        start = {"path": str(self.path.resolve()), "metadata": run_metadata(scene, plan, bus, run_id, realtime, self.host_info),
                 "scene_toml": tomli_w.dumps(scene.resolved),
                 "channels": [{"topic": spec.topic, "metadata": spec.metadata()} for spec in specs]}
        self._process = start_child("zencosim.recordings.recorder_process", [], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=self._log)
        try:
            fcntl.fcntl(self._process.stdin.fileno(), F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:
            pass  # the default capacity only means the tap blocks sooner
        self._send_control(start)
        ready = self._event(READY_TIMEOUT_S, "start")
        if ready["event"] != "ready":
            raise RecordingError(ready.get("reason", f"recorder of {self.path} failed to start"))

    def _declare(self, specs: list[ChannelSpec], realtime: bool) -> None:
        """What the tap needs to know of the channels."""
        if len(specs) > 255:
            raise RecordingError(f"{self.path}: {len(specs)} channels; a recording holds at most 255")
        self._paced = realtime
        self._index = {tuple(spec.topic.split("/")): index for index, spec in enumerate(specs)}
        self._topics = [spec.topic for spec in specs]
        self._status = self._topics.index(STATUS_TOPIC)

    def tap(self, source: str, channel: str, data: bytes) -> None:
        """A message of the in-process replica (``manager.scheme.replica``)."""
        index = self._index[source, channel]
        status = index == self._status
        if status:
            self._stamps.append(time_ns())
        self._channels.append(index)
        self._messages.append(data)
        if status and (self._paced or len(self._messages) >= BATCH_MESSAGES):
            self.flush()  # the status opens a step: the batch holds whole steps

    def flush(self) -> None:
        """Hand what the tap holds to the recorder process now.

        SIGINT and SIGTERM end a run by an exception wherever it is (``cli.main``): one that cut a
        ``tap`` short leaves a channel index (or a stamp) without its message, which is dropped here,
        uncounted; and the frame is sent, counted and cleared with those signals deferred, so that it
        is sent whole and counted exactly once."""
        n = min(len(self._channels), len(self._messages))
        if not n:
            return
        with _interrupts_deferred():
            channels = bytes(self._channels[:n])
            stamps = self._stamps[:channels.count(self._status)]
            self._write_frame(BATCH, b"".join((BATCH_HEAD.pack(n, len(stamps)), channels,
                                               array("I", map(len, self._messages[:n])).tobytes(),
                                               array("q", stamps).tobytes(), *self._messages[:n])))
            self._tapped.update(channels)
            self._channels.clear()
            self._messages.clear()
            self._stamps.clear()

    @property
    def published(self) -> dict[str, int]:
        """The messages the tap handed over, per channel."""
        return {topic: self._tapped[index] for index, topic in enumerate(self._topics)}

    def finish(self, outcome: str) -> dict:
        """Tell the recorder how the run ended and what the tap handed over; wait for the file to be
        complete and return its end record."""
        if self.result is not None:
            return self.result
        if self._process is None:
            raise RecordingError(f"recorder of {self.path} was never started")
        if not self._process.stdin.closed:
            try:
                self.flush()
                self._send_control({"outcome": outcome, "published": self.published})
                self._process.stdin.close()
            except BrokenPipeError:
                pass  # the recorder is gone; its exit is reported below
        end = self._event(FINISH_TIMEOUT_S, "finish")
        self._process.wait()
        self.result = {key: value for key, value in end.items() if key != "event"}
        return self.result

    def close(self) -> None:
        """End the recorder process if it is still there (after a failure to start or finish)."""
        if self._process is not None and self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(5.0)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        self._log.close()

    def _send_control(self, message: dict) -> None:
        self._write_frame(CONTROL, json.dumps(message).encode())

    def _write_frame(self, kind: int, payload: bytes) -> None:
        self._process.stdin.write(FRAME.pack(kind, len(payload), time_ns()))
        self._process.stdin.write(payload)
        self._process.stdin.flush()

    def _event(self, timeout_s: float, what: str) -> dict:
        """The recorder's next JSON line on standard output."""
        stdout = self._process.stdout
        if not select.select([stdout], [], [], timeout_s)[0]:
            raise RecordingError(f"recorder of {self.path} did not {what} within {timeout_s:g} s{self._log_tail()}")
        line = stdout.readline()
        if not line:
            self._process.wait()
            raise RecordingError(f"recorder of {self.path} exited with code {self._process.returncode}"
                                 f"{self._log_tail()}")
        return json.loads(line)

    def _log_tail(self) -> str:
        self._log.seek(0)
        text = self._log.read().decode(errors="replace").strip()
        return ":\n" + "\n".join(text.splitlines()[-15:]) if text else ""
