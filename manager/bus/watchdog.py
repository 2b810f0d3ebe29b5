"""The watched in-process run: ``zencosim run --bus inproc`` runs in a child process that its parent watches.

In process every model shares the run's process, so a model that ends that process — ``os._exit()`` in Python,
``exit()`` or a segmentation fault in an FMU's C code, ``abort()`` — would end the run with an exit status that
says nothing (0 for ``os._exit(0)``), and one that hangs would hang it. The command line therefore forks before the
run (:func:`watched`): the child runs the command as it always did, the parent only waits for it.

They share one page (:class:`ModelWatch`): the child writes its subsystems' names and ``manager.timeout`` once,
then, around every call into a model (its constructor, every command of the stepping loop; in the loop only models
that are not zencosim's own, which alone can end the process), which subsystem it is in and from what simulation
time; as its command ends it writes that it has ended. The parent, when the child ends
without that mark, names the subsystem it was in and how the process ended (``exited with code 0``, ``killed by
SIGSEGV``: exit status 1), once the run's recorder, whose process the child names there too, has finished the file
with what the run had handed over (so that the file is complete when the command returns); when one call into a
model lasts longer than ``manager.timeout`` — as the stall clock counts (``manager.bus.stall``: not the time the
child waited for a CPU; or the child's own CPU time) — it kills the child and names the subsystem as the Zenoh bus
does a subsystem that does not answer (exit status 1). A constructor is not timed (an FMU may unpack and load a
large binary on a busy machine): a model that hangs there is interrupted with Ctrl-C.

Signals: the parent blocks SIGINT, SIGTERM and SIGHUP and passes each on to the child, except one the terminal sent
to its whole foreground process group (``si_code`` ``SI_KERNEL``), which the child has received itself; the child
ends with its parent (``PR_SET_PDEATHSIG``), as the run's other child processes do.

Linux only (``WATCHABLE``: ``sigtimedwait`` and ``PR_SET_PDEATHSIG``); elsewhere the run is not watched. A run
started from Python (``zencosim.run``) runs in the caller's process, unwatched: :func:`model_watch` is then
the unshared :data:`UNWATCHED`, whose marks nobody reads, and endpoints are not wrapped (no cost per step).
"""
from __future__ import annotations

import ctypes
import json
import mmap
import os
import signal
import sys
import time
from contextlib import AbstractContextManager, contextmanager
from typing import Callable, Iterator

from zencosim.manager.bus.children import exit_reason, wait_while_working
from zencosim.manager.bus.stall import StallClock

# the int64 slots of the shared page
SUBSYSTEM, PHASE, CALLS, T_NS, TIMEOUT_NS, ENDED, NAMES_BYTES, RECORDER, SAID_BYTES = range(9)
NAMES_AT, SAID_AT, PAGE_BYTES = 128, 1 << 15, 1 << 16  # the subsystems' names (JSON) from byte NAMES_AT, a line
# the parent says if the child ends in a model (``say_if_ended``) from byte SAID_AT
CONSTRUCTING, STEPPING = 1, 2  # PHASE: what the child runs of the subsystem it is in
POLL_S = 0.25  # how often the parent looks at a child that has not ended
PASSED_ON = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
SI_KERNEL = 0x80  # siginfo's si_code of a signal the kernel sent (the terminal's Ctrl-C to its foreground group)
PR_SET_PDEATHSIG = 1
WATCHABLE = sys.platform.startswith("linux") and hasattr(signal, "sigtimedwait")  # where watched() can run


class ModelWatch:
    """The page a watched run's child marks and its parent reads (see the module text)."""

    def __init__(self, shared: bool) -> None:
        self.shared = shared
        self._page = mmap.mmap(-1, PAGE_BYTES) if shared else bytearray(PAGE_BYTES)
        self.slots = memoryview(self._page)[:NAMES_AT].cast("q")
        self.slots[SUBSYSTEM] = -1
        self._order: dict[str, int] = {}

    def start(self, names: list[str], timeout_s: float) -> None:
        """The run's subsystems (in the order their marks refer to) and its ``manager.timeout``."""
        self._order = {name: i for i, name in enumerate(names)}
        text = json.dumps(names).encode()[:SAID_AT - NAMES_AT]
        self._page[NAMES_AT:NAMES_AT + len(text)] = text
        self.slots[NAMES_BYTES] = len(text)
        self.slots[TIMEOUT_NS] = int(timeout_s * 1e9)

    def names(self) -> list[str]:
        """The names :meth:`start` wrote, as the other process reads them from the page."""
        try:
            return json.loads(bytes(self._page[NAMES_AT:NAMES_AT + self.slots[NAMES_BYTES]]) or b"[]")
        except ValueError:  # cut at the page's end: more subsystems than the page holds names for
            return []

    def say_if_ended(self, line: str) -> None:
        """A line the parent writes on its standard output should the child end before its command does (a verdict
        given before a re-run goes on into a model that may end the process: ``replay --verify``)."""
        text = line.encode()[:PAGE_BYTES - SAID_AT]
        self._page[SAID_AT:SAID_AT + len(text)] = text
        self.slots[SAID_BYTES] = len(text)

    def said(self) -> str:
        """The line :meth:`say_if_ended` wrote, as the other process reads it ("" when none)."""
        return bytes(self._page[SAID_AT:SAID_AT + self.slots[SAID_BYTES]]).decode(errors="replace")

    def recording(self, pid: int) -> None:
        """The run's recorder is process ``pid``: a parent whose child ended before the run did waits for it to finish
        the file (it gets SIGTERM and drains its pipe, ``recordings.recorder_process``)."""
        self.slots[RECORDER] = pid

    def index(self, name: str) -> int:
        """The number the marks give subsystem ``name`` (its place among the names given to :meth:`start`; -1, no
        mark, for a name it was not given)."""
        return self._order.get(name, -1)

    @contextmanager
    def marking(self, index: int, phase: int, t_ns: int = 0) -> Iterator[None]:
        """Marks a call into subsystem number ``index``: its constructor (``CONSTRUCTING``) or its step from time
        ``t_ns`` (``STEPPING``)."""
        slots = self.slots
        slots[SUBSYSTEM], slots[PHASE], slots[T_NS] = index, phase, t_ns
        slots[CALLS] += 1
        try:
            yield
        finally:
            slots[SUBSYSTEM] = -1

    def marking_statements(self, index: int, t_ns: str, slots: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """``marking(index, STEPPING, t_ns)`` as statements around a step that a generated loop runs
        (``manager.scheme.compiled``): (before, after), ``t_ns`` the text of the step's start [ns], ``slots`` the
        name the statements know :attr:`slots` by. A step that raises leaves the mark: whoever catches it clears it
        (``clear``)."""
        return ((f"{slots}[{SUBSYSTEM}], {slots}[{PHASE}], {slots}[{T_NS}] = {index}, {STEPPING}, {t_ns}",
                 f"{slots}[{CALLS}] += 1"), (f"{slots}[{SUBSYSTEM}] = -1",))

    def clear(self) -> None:
        """No call into a model is under way (its step raised, ``marking_statements``)."""
        self.slots[SUBSYSTEM] = -1

    def constructing(self, name: str) -> AbstractContextManager:
        """Marks the construction of subsystem ``name`` (one of the names given to :meth:`start`)."""
        return self.marking(self.index(name), CONSTRUCTING)

    def endpoints(self, endpoints: dict, marked: set[str]) -> dict:
        """The in-process bus's endpoints (``subsystems.process.endpoint``); those of ``marked`` mark their calls when
        watched."""
        if not self.shared:
            return endpoints
        return {name: _WatchedEndpoint(endpoint, self.index(name), self) if name in marked else endpoint
                for name, endpoint in endpoints.items()}

    def where(self) -> tuple[str, str] | None:
        """The subsystem the child is in and what it runs there (``("S2", "its step from t = 0.01 s")``), or None."""
        index, names = self.slots[SUBSYSTEM], self.names()
        if not 0 <= index < len(names):
            return None
        doing = ("its constructor" if self.slots[PHASE] == CONSTRUCTING
                 else f"its step from t = {self.slots[T_NS] * 1e-9:g} s")
        return names[index], doing


class _WatchedEndpoint:
    """A subsystem endpoint whose every call is marked (``STEPPING`` from the subsystem's time)."""

    __slots__ = ("endpoint", "index", "watch", "subsystem")

    def __init__(self, endpoint, index: int, watch: ModelWatch) -> None:
        self.endpoint, self.index, self.watch, self.subsystem = endpoint, index, watch, endpoint.subsystem

    def handle(self, data: bytes) -> bytes:
        with self.watch.marking(self.index, STEPPING, self.subsystem.t_ns):
            return self.endpoint.handle(data)


UNWATCHED = ModelWatch(shared=False)
_active = UNWATCHED


def model_watch() -> ModelWatch:
    """This process's watch: the shared one in a watched run's child, else :data:`UNWATCHED`."""
    return _active


def watched(command: Callable[[], int], failed: Callable[[str], None]) -> int:
    """Run ``command`` (it returns an exit status) in a child process and return its exit status, or 1 with one line
    said naming the subsystem when the child ended without finishing or a model's call outlasted the
    timeout; 130 when it ended so after an interrupt was passed on to it. ``failed(reason)`` says why a run failed.
    """
    global _active
    watch = ModelWatch(shared=True)
    sys.stdout.flush()
    sys.stderr.flush()
    previous_mask = signal.pthread_sigmask(signal.SIG_BLOCK, (*PASSED_ON, signal.SIGCHLD))
    pid = os.fork()
    if pid == 0:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)
        _end_with(os.getppid())
        _active = watch
        try:
            return command()
        finally:
            watch.slots[ENDED] = 1
    try:
        return _wait(pid, watch, failed)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)


def _end_with(parent: int) -> None:
    """SIGTERM to this child when its parent dies (Linux; an interrupt, as every child of a run gets)."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGTERM)


def _wait(pid: int, watch: ModelWatch, failed: Callable[[str], None]) -> int:
    """Wait for the child ``pid``: pass signals on, time the calls into models, and name how it ended."""
    interrupted, timed_out = False, None
    calls, clock, run = -1, StallClock(), {"run": pid}
    while True:
        info = signal.sigtimedwait((*PASSED_ON, signal.SIGCHLD), POLL_S)
        if info is not None and info.si_signo != signal.SIGCHLD:
            interrupted = True
            if info.si_code != SI_KERNEL:  # not the terminal's, which the child's process group received too
                os.kill(pid, info.si_signo)
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        now = time.monotonic()
        if watch.slots[SUBSYSTEM] < 0 or watch.slots[PHASE] != STEPPING or watch.slots[CALLS] != calls:
            calls = watch.slots[CALLS]
            clock.restart(now)
            clock.look(now, run)
            continue
        clock.look(now, run)
        if watch.slots[TIMEOUT_NS] and clock.verdict(watch.slots[TIMEOUT_NS] * 1e-9, list(run)) is not None:
            timed_out = watch.where()
            if timed_out is not None:  # else it has just returned
                os.kill(pid, signal.SIGKILL)
    code = os.waitstatus_to_exitcode(status)
    if watch.slots[RECORDER] and not wait_while_working(watch.slots[RECORDER], watch.slots[TIMEOUT_NS] * 1e-9 or 10.0):
        print(f"the recorder (process {watch.slots[RECORDER]}) makes no progress finishing its file; not waited for",
              file=sys.stderr)
    if watch.slots[ENDED]:
        if code >= 0:
            return code
        failed(f"the run ended, then its process was {exit_reason(code)} as it closed (a model's clean-up)")
        return 1
    if watch.said() and not interrupted:
        print(watch.said(), flush=True)
    if timed_out is not None:
        name, doing = timed_out
        failed(f"subsystem {name}: did not answer within the timeout of {watch.slots[TIMEOUT_NS] * 1e-9:g} s "
               f"(manager.timeout): {doing} did not return, and the run's process was ended (in process every "
               "model shares it; over Zenoh each has its own)")
        return 1
    if interrupted:
        print("interrupted", file=sys.stderr)
        return 130
    where = watch.where()
    if where is None:
        failed(f"the run's process {exit_reason(code)} before the run ended, outside any model's call")
    else:
        failed(f"subsystem {where[0]}: the model ended the run's process in {where[1]} ({exit_reason(code)}; "
               "in process every model shares it, over Zenoh each has its own)")
    return 1
