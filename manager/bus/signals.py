"""Signals that end a process, noted by a handler that takes no lock.

Python runs a signal handler in the main thread between two bytecodes, wherever that thread is, even
inside another handler. A handler that takes a lock (``threading.Event.set`` does) deadlocks when it
lands where that lock is already held, and this happens: when a manager dies, Linux sends each of its
children the parent-death signal again every time it hands them on from one of the manager's exiting
threads to the next, so the handlers nest. A subsystem process and a recorder were seen to hang so,
forever. The handler here only stores the signal's name; the main thread acts on it when it next looks.
"""
from __future__ import annotations

import contextlib
import signal
import threading


class SignalNote:
    """Installs itself as the handler of ``signums``; ``signum`` is the first that arrived, or None."""

    def __init__(self, *signums: int) -> None:
        self.signum: int | None = None
        for signum in signums:
            signal.signal(signum, self._note)

    def _note(self, signum: int, _frame) -> None:
        if self.signum is None:
            self.signum = signum

    @property
    def received(self) -> str | None:
        """``"signal SIGTERM"`` (say) once a signal arrived, else None."""
        return None if self.signum is None else f"signal {signal.Signals(self.signum).name}"


ENDING_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def interpose(handler) -> dict[int, object]:
    """Install ``handler`` for SIGINT and SIGTERM (in the main thread) and return the handlers it replaced; a
    handler installed from outside Python (``getsignal``: None) is left alone: it could not be put back."""
    previous = {signum: found for signum in ENDING_SIGNALS if (found := signal.getsignal(signum)) is not None}
    for signum in previous:
        signal.signal(signum, handler)
    return previous


def act_as(handler, signum: int, frame) -> None:
    """What ``handler`` (a replaced one) would have done with ``signum``: a function is called (Python's SIGINT
    handler raises KeyboardInterrupt), the default action is taken, an ignored signal is ignored."""
    if callable(handler):
        handler(signum, frame)
    elif handler == signal.SIG_DFL:
        signal.signal(signum, signal.SIG_DFL)
        signal.raise_signal(signum)


def restore(previous: dict[int, object]) -> None:
    """Put back the handlers ``interpose`` replaced."""
    for signum, handler in previous.items():
        signal.signal(signum, handler)


class DeferredSignals:
    """SIGINT and SIGTERM handlers for the length of a run (install in the main thread; ``restore`` puts back the
    handlers that were there): inside ``held()``, entered in the thread that installed them, the signals that
    arrive are noted and act when the block ends, in the order they came; anywhere else a signal acts at once.
    A signal acts as the handler that was there before would have: a function is called (Python's SIGINT
    handler raises KeyboardInterrupt), the default action is taken, an ignored signal is ignored.

    Holding is a flag, not a swap of handlers: ``signal.signal`` costs microseconds per call (its conversions to
    enums), which a recorder's flush, several times a second, paid for both signals twice."""

    def __init__(self) -> None:
        self.thread = threading.get_ident()
        self._holding = False
        self._arrived: list[int] = []  # while holding, in order of arrival, each once
        self.previous = interpose(self._arrive)

    def _arrive(self, signum: int, frame) -> None:
        if self._holding:
            if signum not in self._arrived:
                self._arrived.append(signum)
            return
        self._act(signum, frame)

    def _act(self, signum: int, frame) -> None:
        act_as(self.previous[signum], signum, frame)

    @contextlib.contextmanager
    def held(self):
        """Signals that arrive inside the block act when it ends (only in the installing thread: Python runs
        handlers in the main thread, so elsewhere no signal can cut the block short)."""
        if threading.get_ident() != self.thread:
            yield
            return
        self._holding = True
        try:
            yield
        finally:
            self._holding = False
            arrived, self._arrived = self._arrived, []
            for signum in arrived:
                self._act(signum, None)

    def restore(self) -> None:
        """Put back the handlers that were there before."""
        restore(self.previous)


class InterruptWatch:
    """A context manager, entered in the main thread for the length of an in-process run: SIGINT and SIGTERM that
    arrive are noted, then act as the handlers that were there would (``act_as``), so that a
    KeyboardInterrupt can be told from one that the running code (a model) raised itself: see
    :func:`raised_by_code`."""

    active: "InterruptWatch | None" = None  # the one entered, if any

    def __init__(self) -> None:
        self.received = False
        self.previous: dict[int, object] = {}
        self.outer: InterruptWatch | None = None

    def __enter__(self) -> "InterruptWatch":
        if threading.current_thread() is threading.main_thread():
            self.previous = interpose(self._note)
            self.outer, InterruptWatch.active = InterruptWatch.active, self
        return self

    def _note(self, signum: int, frame) -> None:
        self.received = True
        act_as(self.previous[signum], signum, frame)

    def __exit__(self, *_exc) -> None:
        if InterruptWatch.active is self:
            InterruptWatch.active = self.outer
        restore(self.previous)
        self.previous = {}


def raised_by_code() -> bool:
    """Whether the KeyboardInterrupt being handled was raised by the running code itself (a model), not by the user:
    outside the main thread always (Python runs signal handlers in the main thread only); in it, when an
    :class:`InterruptWatch` is active and noted no SIGINT or SIGTERM (without one it cannot be told: the user's)."""
    if threading.current_thread() is not threading.main_thread():
        return True
    watch = InterruptWatch.active
    return watch is not None and not watch.received
