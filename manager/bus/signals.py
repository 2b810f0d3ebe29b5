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


class DeferredSignals:
    """SIGINT and SIGTERM handlers for the length of a run (install in the main thread; ``restore`` puts back the
    handlers that were there): inside ``held()``, entered in the thread that installed them, the signals that
    arrive are noted and act when the block ends, in the order they came; anywhere else a signal acts at once.
    A signal acts as the handler that was there before would have: a function is called (Python's SIGINT
    handler raises KeyboardInterrupt), the default action is taken, an ignored signal is ignored.

    Holding is a flag, not a swap of handlers: ``signal.signal`` costs microseconds per call (its conversions to
    enums), which a recorder's flush, several times a second, paid for both signals twice."""

    SIGNUMS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.thread = threading.get_ident()
        # a handler installed from outside Python (getsignal: None) is left alone: it could not be put back
        self.previous = {signum: handler for signum in self.SIGNUMS
                         if (handler := signal.getsignal(signum)) is not None}
        self._holding = False
        self._arrived: list[int] = []  # while holding, in order of arrival, each once
        for signum in self.previous:
            signal.signal(signum, self._arrive)

    def _arrive(self, signum: int, frame) -> None:
        if self._holding:
            if signum not in self._arrived:
                self._arrived.append(signum)
            return
        self._act(signum, frame)

    def _act(self, signum: int, frame) -> None:
        handler = self.previous[signum]
        if callable(handler):
            handler(signum, frame)
        elif handler == signal.SIG_DFL:
            signal.signal(signum, signal.SIG_DFL)
            signal.raise_signal(signum)

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
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)
