"""The manager's handle on a recorder process (recordings.recorder_process) and a live view
(recordings.rerun_live): the observers of a run.

``start`` spawns each process (it dies with the manager), sends it the run's description and waits until it is
ready — for as long as it makes progress, so that a busy machine slows its start but never fails it — and
then lowers it to idle priority (it takes the CPU time the run leaves); ``exchange``, the tap
of the manager's replica (in process, or following a Zenoh run), hands it every message through a pipe —
the tap only appends the messages and their channels to two lists, and every ``BATCH_MESSAGES``
messages (every ``HANDOVER_S`` of a real-time run) they go down the pipe as one frame, to every observer, so
validation, encoding and compression (and the live view) run in the other processes, on the other core.
An in-process run that is not paced hands ``take_steps`` blocks of arrays instead (``manager.scheme.tapped``),
each sent as one STEPS frame from which those processes build the messages (``recordings.steps_frame``), or, from a
generated loop, ``take_rows`` its rows, sent as ROWS frames (``recordings.rows_frame``).
A full pipe blocks the tap: backpressure, never a drop. ``finish`` sends the outcome and what the tap
handed over and returns the recorder's end record (outcome, per-channel published / received / lost).
A recorder that cannot write (a full disk) says why on its standard output before it exits, and the line
that names it gone says so.
"""
from __future__ import annotations

import contextlib
import fcntl
import json
import marshal
import os
import select
import subprocess
import sys
import tempfile
import termios
import threading
import time
from array import array
from pathlib import Path
from time import time_ns
from typing import Callable

import numpy as np
import tomli_w

from zencosim.manager.bus.children import cpu_time_s, exit_reason, process_state, start_child, working
from zencosim.manager.bus.signals import DeferredSignals
from zencosim.manager.bus.watchdog import model_watch
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import Exchange
from zencosim.manager.scheme.tapped import PendingSteps, RowsBlock, StepsBlock
from zencosim.manager.wire.status import Statuses, StatusReport
from zencosim.recordings import RecorderFailed, RecorderLost, RecordingError
from zencosim.recordings.layout import ChannelSpec, channel_specs, run_metadata, status_index
from zencosim.recordings.recorder_process import (BATCH, BATCH_HEAD, CONTROL, FRAME, PENDING, ROWS, STEPS,
                                                  channel_index)
from zencosim.recordings.rows_frame import rows_about, rows_frame
from zencosim.recordings.steps_frame import pending_payload, steps_frame

STALL_S = 10.0  # an observer that makes no progress for this long fails (the scene's manager.timeout, once known)
PROGRESS_LOOK_S = 0.5  # while it is waited for, its CPU time and state are looked at this often [s]
PIPE_BYTES = 1 << 20  # pipe capacity asked of the kernel: room for bursts before the tap blocks
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE")  # a pipe's buffers are pages
BATCH_MESSAGES = 2048  # the tap hands messages over in batches of about this many (at a status message)
HANDOVER_S = 0.01  # and a real-time run's at least every this much run time [s] (a live view's 100 frames/s)
F_SETPIPE_SZ, F_GETPIPE_SZ = 1031, 1032  # Linux fcntl
STOP_WAIT_S = 1.0  # a process whose pipe broke has this long to be reaped before its exit is described
RECORD_LOST = ("stop", "continue")  # what a run does when its recorder process is gone (--record-lost)
# An observer multiplies no matrices: without this, numpy's OpenBLAS starts a worker thread per further CPU, which
# spins (busy-waits) through numpy's import: 0.11 s of CPU at every start, beside the run's own start
OBSERVER_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1"}


def _lowest_priority(pid: int) -> None:
    """Process ``pid`` takes the CPU time the run leaves: SCHED_IDLE (Linux: any other task that wakes up
    preempts it, and it still gets a small share of a busy CPU, so it cannot starve), else nice 19; where
    neither is allowed it competes with the run as an equal. Backpressure, not priority, keeps every message.

    Only once it is ready: started at idle priority on a machine whose cores other work keeps busy, its
    start-up (Python, numpy: about half a second of CPU) got a small share of a CPU and took minutes."""
    try:
        os.sched_setscheduler(pid, os.SCHED_IDLE, os.sched_param(0))
    except (OSError, AttributeError):
        try:
            os.setpriority(os.PRIO_PROCESS, pid, 19)
        except (OSError, AttributeError):
            pass


class _Observer:
    """One child process fed the tap's frames on its standard input: the recorder, or the live view.

    Its input pipe is non-blocking: a write waits for room with ``select``, so that a process that takes
    nothing for ``stall_s`` (frozen, or far behind) is said, while the run still waits for it (backpressure,
    never a drop); a process that is gone raises ``BrokenPipeError``. A ``lossy`` observer (the live view:
    a viewer must not slow the run it shows) is not waited for with a batch: one that finds its pipe
    holding unread bytes and without room for the whole frame is skipped and counted."""

    def __init__(self, module: str, what: str, lossy: bool = False) -> None:
        self.what = what
        self.lossy = lossy
        self.skipped = [0, 0]  # batches skipped, and the macro-steps they held
        self.log = tempfile.TemporaryFile()
        self.process = start_child(module, [], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log,
                                   env={**os.environ, **OBSERVER_ENVIRONMENT})
        self.gone: str | None = None  # why it is gone ("killed by SIGKILL"), once a write found it so
        self.unread: list[str] = []  # lines of its output read while looking for why it failed, not yet taken
        fd = self.process.stdin.fileno()
        try:
            fcntl.fcntl(fd, F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:
            pass  # the default capacity only means the tap blocks sooner
        try:
            self.capacity: int | None = fcntl.fcntl(fd, F_GETPIPE_SZ)  # [bytes] of its pipe
        except OSError:
            self.capacity = None  # cannot tell: a lossy observer is waited for like any other
        self.writes = 0  # writes into its pipe since it was last seen empty (_room_for)
        self.behind = False  # a lossy observer that was skipped a batch and has not taken all it holds since
        os.set_blocking(fd, False)

    def write(self, parts: tuple[bytes, ...], stall_s: float, stalled: Callable[["_Observer", float], None],
              steps: int | None = None) -> None:
        """Write ``parts`` whole; ``stalled(self, waited_s)`` every ``stall_s`` the pipe stays full, and
        ``stalled(self, -waited_s)`` once it takes bytes again after that. ``steps``: the frame is a batch of
        that many macro-steps, which a lossy observer without room skips."""
        fd = self.process.stdin.fileno()
        if steps is not None and self.lossy and (self.behind or not self._room_for(sum(map(len, parts)), len(parts))):
            self.behind = not self._drained()  # skipped until it has taken all it holds: one gap, however
            if self.behind:  # the batches' sizes vary (a small one fits where a large one did not)
                self.skipped[0] += 1
                self.skipped[1] += steps
                return
        self.writes += len(parts)
        stalls, since = 0, 0.0
        for part in parts:
            view = memoryview(part)
            while view:
                try:
                    view = view[os.write(fd, view):]
                    continue
                except BlockingIOError:
                    pass  # no room (or for less than one pipe page): wait for it
                if not select.select([], [fd], [], stall_s)[1]:
                    stalls += 1
                    since = since or time.monotonic() - stall_s
                    stalled(self, stalls * stall_s)
        if stalls:
            stalled(self, since - time.monotonic())

    def _room_for(self, size: int, writes: int) -> bool:
        """Whether the pipe takes ``size`` bytes in ``writes`` writes now; an empty pipe always does (a frame larger
        than the pipe is then written as its reader takes it). A pipe holds whole pages, and a write that does not
        fit in the last page's room starts a new one: each write since the pipe was empty may have left up to a page
        unused (with 147 KB frames, six fitted in 1 MiB by their bytes and the seventh did not: the run waited for
        a frozen live view)."""
        unread = self._unread()
        if unread is None:
            return True  # cannot tell: wait for room
        if self.capacity is None or unread == 0:
            self.writes = 0
            return True
        pages = -(-unread // PAGE_BYTES) + self.writes + -(-size // PAGE_BYTES) + writes  # at the most
        return pages * PAGE_BYTES <= self.capacity

    def _drained(self) -> bool:
        """Whether its pipe holds no unread byte (or that cannot be told)."""
        return not self._unread()

    def _unread(self) -> int | None:
        """The bytes its pipe holds that it has not read (None: cannot tell)."""
        unread = array("i", [0])
        try:
            fcntl.ioctl(self.process.stdin.fileno(), termios.FIONREAD, unread)
        except OSError:
            return None
        return unread[0]

    def ended(self) -> str:
        """How the process ended (``"killed by SIGKILL"``, ``"exited with code 1: writing the file failed: No
        space left on device"`` with the reason it said), waiting for it a moment."""
        try:
            self.process.wait(STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            return "its input is closed, although it runs"
        said = self._said()
        return exit_reason(self.process.returncode) + (f": {said}" if said else "")

    def _said(self) -> str | None:
        """The reason the exited process gave for failing (an ``error`` or ``failed`` event left on its output)."""
        stdout, said = self.process.stdout, None
        while select.select([stdout], [], [], 0)[0]:
            line = stdout.readline()
            if not line:
                break
            self.unread.append(line)  # a line that is not a failure (its end record, sent before a SIGTERM
            try:                      # killed it) is still the next event
                event = json.loads(line)
            except ValueError:
                continue
            if isinstance(event, dict) and event.get("event") in ("error", "failed"):
                said = str(event.get("reason"))
        return said

    def event(self, stall_s: float, doing: str) -> dict:
        """The process's next JSON line on standard output, waited for as long as the process makes progress
        (uses CPU, or waits only for a CPU or its disk: a busy machine slows it, never fails it); :class:`RecorderFailed`
        when it exits first, or makes none for ``stall_s`` (frozen, or waiting for what does not come)."""
        if self.unread:
            return json.loads(self.unread.pop(0))
        stdout, pid = self.process.stdout, self.process.pid
        still_from, cpu = time.monotonic(), cpu_time_s(pid)
        while not select.select([stdout], [], [], PROGRESS_LOOK_S)[0]:
            now, used = time.monotonic(), cpu_time_s(pid)
            if used > cpu or working(pid):
                still_from, cpu = now, used
            elif now - still_from >= stall_s:
                state = process_state(pid) or "uses no CPU and waits"
                raise RecorderFailed(f"the {self.what} did not {doing}: its process {state}, with no progress for "
                                     f"{stall_s:g} s (manager.timeout){self.log_tail()}")
        line = stdout.readline()
        if not line:
            self.process.wait()
            raise RecorderFailed(f"the {self.what} did not {doing}: it {exit_reason(self.process.returncode)}"
                                 f"{self.log_tail()}")
        return json.loads(line)

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(5.0)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()

    def log_tail(self) -> str:
        self.log.seek(0)
        text = self.log.read().decode(errors="replace").strip()
        return ":\n" + "\n".join(text.splitlines()[-15:]) if text else ""


class _ChannelIndices(dict):
    """The channel indices (bytes) of channel ``channel`` of the subsystems of a tuple of names, found once."""

    def __init__(self, index: dict[tuple[str, str], int], channel: str) -> None:
        super().__init__()
        self.index = index
        self.channel = channel

    def __missing__(self, names: tuple[str, ...]) -> bytes:
        self[names] = indices = bytes(self.index[name, self.channel] for name in names)
        return indices


class Recorder:
    """Records one run to ``path`` and/or shows it live in Rerun (``rerun``: ``spawn``, ``connect=ADDR`` or
    ``serve``, ``recordings.rerun_live``): create it, pass it to ``manager.run.execute``, read ``result``
    (the recording's end record; None without a recording).

    A recorder process that is gone (killed, crashed) is said in one line naming it and the step the run
    had reached; ``on_lost`` (``RECORD_LOST``) says what the run does then: ``stop`` raises
    :class:`RecorderLost` (the run fails), ``continue`` goes on unrecorded. A live view that is gone
    is said and left behind. One that takes nothing for the scene's ``manager.timeout`` is said
    (``announce``) and waited for."""

    def __init__(self, path: str | Path | None, host_info: bool = False, rerun: str | None = None,
                 linger: Callable[[dict], None] | None = None, on_lost: str = "stop",
                 announce: Callable[[str], None] | None = None) -> None:
        if on_lost not in RECORD_LOST:
            raise ValueError(f"on_lost {on_lost!r}: expected one of {', '.join(RECORD_LOST)}")
        self.path = check_output_file(path, "recording") if path is not None else None
        self.host_info = host_info  # record the host's name and the scene's path (layout.run_metadata)
        self.rerun = rerun
        self.linger = linger  # called with what the live view said, once it has shown the whole run, before close
        self.on_lost = on_lost
        self.announce = announce or (lambda text: None)
        self.lost: str | None = None  # why the recorder process is gone, when it is
        self._stall_s = STALL_S  # an observer that takes nothing for this long is said (manager.timeout)
        self._step = 0  # the last step whose status went down the pipe
        self._lost_at: tuple[int, dict[str, int]] = (0, {})  # the step and what was handed over when the recorder was lost
        self.result: dict | None = None
        self.live: dict | None = None  # what the live view said when it was ready (e.g. the web viewer's address)
        self.finished = False
        self._observers: list[_Observer] = []
        self._recorder: _Observer | None = None
        self._live: _Observer | None = None
        self._topics: list[str] = []
        self._status = -1  # index of the status channel
        self._channels = bytearray()  # the batch being tapped: channel index of each message
        self._messages: list[bytes] = []  # and the messages but the statuses (in the status log until the flush)
        self._report: StatusReport | None = None  # the run's status, whose log the flush takes the statuses from
        self._names: list[str] = []  # the run's subsystems
        self._about = b""  # what every ROWS frame of the run says of it (recordings.rows_frame)
        self._tapped = np.zeros(0, dtype=np.int64)  # messages handed over, per channel index
        self._signals: DeferredSignals | None = None  # SIGINT and SIGTERM held during a flush, from start to close
        self._log_sent = (0, 0)  # the status log's residuals and times sent in PENDING frames since the last block

    def start(self, scene: Scene, plan: Plan, status: StatusReport, bus: str, run_id: str, realtime: bool) -> None:
        """Start the recorder process and the live view, and wait until they are ready."""
        self._hold_signals()
        specs = self._declare(plan, status, realtime)
        self._stall_s = scene.manager.timeout
        channels = [{"topic": spec.topic, "metadata": spec.metadata()} for spec in specs]
        metadata = run_metadata(scene, plan, bus, run_id, realtime, self.host_info)
        scene_toml = tomli_w.dumps(scene.resolved)
        if self.path is not None:
            self._recorder, _ = self._start(
                "zencosim.recordings.recorder_process", f"recorder of {self.path}",
                {"path": str(self.path.resolve()), "metadata": metadata, "scene_toml": scene_toml, "channels": channels})
            model_watch().recording(self._recorder.process.pid)  # a watched run's parent waits for it (in process)
        if self.rerun is not None:
            self._live, self.live = self._start("zencosim.recordings.rerun_live", f"live view ({self.rerun})",
                                                {"target": self.rerun, "metadata": metadata, "scene_toml": scene_toml,
                                                 "channels": channels}, lossy=True)

    def _start(self, module: str, what: str, start: dict, lossy: bool = False) -> tuple[_Observer, dict]:
        """An observer process given its START frame, once it is ready (waited for as long as it makes progress,
        at normal priority; then lowered to idle priority); and what it said then. One that refuses its START
        (a path it cannot open, a viewer it cannot reach) is bad input (:class:`RecordingError`); one that exits,
        stops making progress or cannot write has failed (:class:`RecorderFailed`)."""
        observer = _Observer(module, what, lossy)
        self._observers.append(observer)
        payload = json.dumps(start).encode()
        try:
            observer.write((FRAME.pack(CONTROL, len(payload), time_ns()), payload), self._stall_s, self._stalled)
        except BrokenPipeError:
            pass  # it exited at once: event() says why
        ready = observer.event(self._stall_s, "start")
        if ready["event"] == "failed":
            raise RecorderFailed(f"the {what} could not start: {ready.get('reason')}")
        if ready["event"] != "ready":
            raise RecordingError(ready.get("reason", f"{what} failed to start"))
        _lowest_priority(observer.process.pid)
        return observer, ready

    def _hold_signals(self) -> None:
        """From now until ``close``, SIGINT and SIGTERM that arrive during a flush act when it ends (in the main
        thread, the only one Python runs handlers in)."""
        if threading.current_thread() is threading.main_thread():
            self._signals = DeferredSignals()

    def _declare(self, plan: Plan, status: StatusReport, realtime: bool) -> list[ChannelSpec]:
        """What the tap needs to know of the run of ``plan``, its channels (returned) and the run's status, whose
        messages it takes from the log its scheme fills (``realtime``: the tap hands a batch over every
        ``HANDOVER_S`` of run time)."""
        specs = channel_specs(plan, status)
        if len(specs) > 255:
            raise RecordingError(f"{self.path}: {len(specs)} channels; a recording holds at most 255")
        self._report = status
        self._names = [s.name for s in plan.subsystems]
        self._about = rows_about(plan)  # of every ROWS frame
        self._topics = [spec.topic for spec in specs]
        self._tapped = np.zeros(len(specs), dtype=np.int64)
        self._status = status_index(specs)
        self._index = index = channel_index(specs)  # (source, channel) → index
        self.exchange = self._tap(index, max(1, round(HANDOVER_S * 1e9 / status.base_step_ns)) if realtime else None)
        if not realtime:  # a real-time run's tap hands a batch over every HANDOVER_S: exchange by exchange
            self.take_steps, self.take_rows, self.take_pending = self._take_steps, self._take_rows, self._take_pending
        return specs

    def _take_steps(self, block: StepsBlock) -> None:
        """The tap of a direct (in-process) run, a block of exchanges as arrays at a time (``manager.scheme.tapped``):
        sent as one STEPS frame (``recordings.steps_frame``), after what ``exchange`` holds (the initialisation's
        requests); counted and cleared with SIGINT and SIGTERM deferred, as ``flush`` does."""
        self.flush()
        with self._signals.held() if self._signals is not None else contextlib.nullcontext():
            statuses = self._report.take(block.statuses)
            self._log_sent = (0, 0)  # the recorder process drops what PENDING frames held: all of the log is new
            if self._all_gone:
                return
            counts = self._counts(block.names, [len(s.steps) for s in block.subsystems],
                                  [len(s.ticks) for s in block.subsystems], block.statuses)
            self._send(STEPS, steps_frame(block, statuses), self._reached(statuses), counts, block.last)

    def _take_pending(self, pending: PendingSteps) -> None:
        """Requests a direct run took since it last handed something over, not yet a block (``TakenSteps.hand_over``),
        and the statuses logged since then: sent to the recorder process alone as a PENDING frame, which it records
        only if no block of them follows (the run's process ended), so they are not counted; after what ``exchange``
        holds, with SIGINT and SIGTERM deferred, as ``flush`` does."""
        self.flush()
        recorder = self._recorder
        with self._signals.held() if self._signals is not None else contextlib.nullcontext():
            if recorder is None or recorder.gone is not None:
                return
            start_ns, residuals, times = self._report.log()
            logged_residuals, logged_times = self._log_sent
            payload = pending_payload(pending, self._report.n_residuals,
                                      (start_ns, residuals[logged_residuals:], times[logged_times:]))
            self._log_sent = (len(residuals), len(times))
            try:  # small: one write
                recorder.write((FRAME.pack(PENDING, len(payload), time_ns()) + payload,), self._stall_s, self._stalled)
            except BrokenPipeError:
                self._lose(recorder)

    def _take_rows(self, block: RowsBlock) -> None:
        """The tap of a generated loop (``manager.scheme.compiled``), its rows a block at a time (``TakenRows``): sent
        as one ROWS frame (``recordings.rows_frame``), as ``_take_steps`` sends a STEPS frame."""
        self.flush()
        with self._signals.held() if self._signals is not None else contextlib.nullcontext():
            if self._all_gone:
                return
            steps = block.status_steps
            counts = self._counts(self._names, [block.replies] * len(self._names),
                                  [block.requests] * len(self._names), len(steps))
            frame = rows_frame(block, self._about, time_ns() - time.perf_counter_ns())
            self._send(ROWS, frame, steps[-1] if steps else self._step, counts, block.last)

    def _counts(self, names: list[str], replies: list[int], commands: list[int], statuses: int) -> np.ndarray:
        """The messages per channel of a block: the replies and the commands of each of the subsystems ``names``, and
        ``statuses``."""
        counts = np.zeros(len(self._topics), dtype=np.int64)
        for name, n_replies, n_commands in zip(names, replies, commands):
            counts[self._index[name, "y"]] = n_replies
            counts[self._index[name, "commands"]] = n_commands
        counts[self._status] = statuses
        return counts

    def _tap(self, index: dict[tuple[str, str], int], every: int | None
             ) -> Callable[[dict[str, bytes] | None, Exchange | None], None]:
        """The Tap of a replica (``manager.scheme.replica``): ``exchange(replies, request)``, once per exchange on
        the stepping loop. It adds the exchange to the batch: the replies (those the last request awaited, in that
        order) and the request's commands to the messages, then the channel indices of the replies, of the
        request's status (only its index: ``flush`` takes the message from the status log) and of the commands —
        derived from the names once per ``request.shape`` (``Exchange``), else per exchange. A batch holds whole
        exchanges and is handed over before one that reports a status, so it holds whole steps; a message goes in
        before its channel index (``flush`` drops messages whose indices an interrupt cut off). ``index``: the
        channel index of each (source, channel); ``every``: a real-time run's batches hold at most this many steps
        (None: any number)."""
        channels, batch = self._channels, self._messages
        flush = self.flush
        replies_of, commands_of = _ChannelIndices(index, "y"), _ChannelIndices(index, "commands")
        status_byte = bytes([self._status])
        shaped: dict[int, bytes] = {}  # the channel indices of an exchange, per shape
        awaited: tuple[str, ...] = ()
        handover = every or sys.maxsize
        flush_at = handover  # the step whose status a batch is handed over at, at the latest

        def exchange(replies: dict[str, bytes] | None, request: Exchange | None) -> None:
            nonlocal awaited, flush_at
            if request is None:  # the scheme has ended: the replies it took last
                if replies:
                    batch.extend(replies.values())
                    channels.extend(replies_of[awaited])
                return
            status = request.status
            if status is not None and (len(channels) >= BATCH_MESSAGES or status >= flush_at):
                flush()
                flush_at = status + handover
            if replies:
                batch.extend(replies.values())
            batch.extend(request.sends.values())
            indices = shaped.get(request.shape)
            if indices is None:  # a new shape, or none (never a key)
                indices = (replies_of[awaited] + (b"" if status is None else status_byte)
                           + commands_of[tuple(request.sends)])
                if request.shape is not None:
                    shaped[request.shape] = indices
            channels.extend(indices)
            awaited = request.awaits
        return exchange

    def flush(self, last: bool = False) -> None:
        """Hand what the tap holds to the recorder process now (``last``: the run's last batch, which the live
        view is not skipped for, so that it shows how the run ended).

        The batch's statuses are taken from the status log, in step order, and go after its other messages
        (``recorder_process.BATCH``).

        SIGINT and SIGTERM end a run by an exception wherever it is (``cli.main``): one that cut the
        tap (``exchange``) short leaves messages without their channel indices, which are dropped here,
        uncounted; and the frame is sent, counted and cleared with those signals deferred, so that it
        is sent whole and counted exactly once."""
        channels, messages = self._channels, self._messages
        if not channels:
            messages.clear()
            return
        with self._signals.held() if self._signals is not None else contextlib.nullcontext():
            n_statuses = channels.count(self._status)
            del messages[len(channels) - n_statuses:]  # the last messages, whose indices never came
            statuses = self._report.take(n_statuses)
            if not self._all_gone:
                self._send(BATCH, b"".join((BATCH_HEAD.pack(len(channels), n_statuses, len(statuses.messages)),
                                            channels, statuses.stamps.tobytes(), statuses.messages,
                                            marshal.dumps(messages))), self._reached(statuses),
                           np.bincount(np.frombuffer(channels, dtype=np.uint8), minlength=len(self._topics)), last)
            channels.clear()
            messages.clear()

    @property
    def _all_gone(self) -> bool:
        """Every observer is gone (``--record-lost continue``): what the tap takes is dropped."""
        return bool(self._observers) and all(observer.gone for observer in self._observers)

    def _send(self, kind: int, payload: bytes, step: int, counts: np.ndarray, last: bool) -> None:
        """Send a frame holding ``counts`` messages per channel, the last status of ``step``, and count them handed
        over; with SIGINT and SIGTERM deferred (``flush``). ``last``: the run's last frame, which the live view is
        not skipped for; other frames tell it how many macro-steps they hold."""
        self._write_frame(kind, payload, None if last else step - self._step)
        self._tapped += counts
        self._step = step

    def _reached(self, statuses: Statuses) -> int:
        """The step of the last of ``statuses``, or the step reached before them when there are none."""
        return int(statuses.steps[-1]) if len(statuses.steps) else self._step

    @property
    def pids(self) -> list[int]:
        """The process ids of the recorder and the live view, as started."""
        return [observer.process.pid for observer in self._observers]

    @property
    def live_skipped(self) -> tuple[int, int]:
        """The batches, and the macro-steps they held, not sent to the live view because it had fallen behind."""
        return tuple(self._live.skipped) if self._live is not None else (0, 0)

    @property
    def published(self) -> dict[str, int]:
        """The messages the tap handed over, per channel."""
        return dict(zip(self._topics, self._tapped.tolist()))

    def finish(self, outcome: str) -> dict | None:
        """Tell the recorder and the live view how the run ended and what the tap handed over; wait for the
        file to be complete and return its end record (None without a recording; for a recorder that is gone,
        what is known: the outcome says when it was lost, ``messages`` and ``lost`` are None). A recorder that goes
        only now (a disk that fills with the last chunks) under ``--record-lost stop`` raises :class:`RecorderLost`
        once every observer is done: the run completed, its recording did not."""
        if self.finished:
            return self.result
        if not self._observers:
            raise RecordingError("the recorder was never started")
        self.finished = True
        lost_before = self.lost is not None  # then the run has said so (or stopped for it) already
        try:
            self.flush(last=True)
            if self._live is not None and self._live.skipped[0]:
                batches, steps = self._live.skipped
                self.announce(f"the live view fell behind the run: {batches} batches ({steps} macro-steps) were not sent "
                              "to it" + ("; the recording holds every step" if self._recorder is not None else ""))
            self._write_frame(CONTROL, json.dumps({"outcome": outcome, "published": self.published}).encode())
        except RecorderLost:
            pass  # in self.lost: raised below, once every observer is done
        for observer in self._observers:
            if observer.gone is None and not observer.process.stdin.closed:
                try:
                    observer.process.stdin.close()
                except BrokenPipeError:
                    pass
        for observer in self._observers:
            try:  # one that is gone may have finished before it went (SIGTERM): its end is on its output
                end = observer.event(self._stall_s if observer.gone is None else STOP_WAIT_S, "finish")
            except RecorderFailed:
                if observer.process.poll() is None and observer.gone is None:
                    raise  # it stopped making progress before it finished
                if observer.gone is None:
                    self._lose(observer, ended=True)  # it died after the last frame
                continue
            if end.get("event") == "failed":  # it could not write the end of the file (a full disk)
                if observer.gone is None:
                    self._lose(observer, ended=True, said=end.get("reason"))
                continue
            if observer is self._recorder:
                observer.process.wait()
                self.result = {key: value for key, value in end.items() if key != "event"}
        if self.result is None and self._recorder is not None and self._recorder.gone is not None:
            step, published = self._lost_at
            self.result = {"outcome": f"the recorder was lost at step {step} ({self._recorder.gone}); the run: "
                                      + ("stopped for it" if self.lost in outcome else outcome),
                           "path": str(self.path), "messages": None, "lost": None,
                           "channels": {topic: {"published": count, "received": None, "lost": None}
                                        for topic, count in published.items()}, "malformed": None}
            if not lost_before and self.on_lost == "stop":  # lost during finish, its file not finished
                raise RecorderLost(self.lost)
        return self.result

    def close(self) -> None:
        """End the observer processes that are still there (after a failure to start or finish; a live view
        serving the web viewer lasts until then: ``linger`` waits)."""
        try:
            if self.linger is not None and self.finished and self.live is not None:
                self.linger(self.live)
        finally:
            for observer in self._observers:
                observer.close()
            if self._signals is not None:
                self._signals.restore()
                self._signals = None

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        """Send a frame to every observer (``steps``: a batch of that many macro-steps, which the live view
        may skip)."""
        parts = (FRAME.pack(kind, len(payload), time_ns()), payload)
        for observer in self._observers:
            if observer.gone is None:
                try:
                    observer.write(parts, self._stall_s, self._stalled, steps)
                except BrokenPipeError:
                    self._lose(observer)

    def _lose(self, observer: _Observer, ended: bool = False, said: str | None = None) -> None:
        """``observer``'s process is gone (``said``: the reason it gave, already read from its output): say so; for
        the recorder under ``on_lost == "stop"``, raise :class:`RecorderLost` (``ended``: the run has ended, and
        ``finish`` raises it when it is done, as for a recorder lost while ``finish`` sends its last frames)."""
        observer.gone = observer.ended()
        if said and said not in observer.gone:
            observer.gone += f": {said}"
        if observer is not self._recorder:
            self.announce(f"the {observer.what} is gone ({observer.gone}); the run goes on without it")
            return
        self._lost_at = (self._step, self.published)
        self.lost = (f"the recorder of {self.path} is gone ({observer.gone}) at step {self._step}: the file ends with "
                     f"its last chunk written, before that step ('zencosim inspect {self.path}' says where)")
        if ended:
            if self.on_lost == "continue":
                self.announce(f"{self.lost}; the run had ended (--record-lost continue)")
            return
        if self.on_lost == "stop":
            raise RecorderLost(f"{self.lost}; with --record-lost continue the run goes on without it")
        self.announce(f"{self.lost}; the run goes on unrecorded (--record-lost {self.on_lost})")

    def _stalled(self, observer: _Observer, waited_s: float) -> None:
        """``observer`` has taken nothing for ``waited_s`` (negative: it takes messages again after that long)."""
        if waited_s < 0:
            self.announce(f"the {observer.what} takes messages again after {-waited_s:.1f} s")
        elif waited_s == self._stall_s:  # said once per stall
            state = process_state(observer.process.pid) or "runs but takes nothing"
            self.announce(f"the {observer.what} has taken nothing for {waited_s:g} s: its process {state}; "
                          "the run waits for it (nothing is dropped)")
