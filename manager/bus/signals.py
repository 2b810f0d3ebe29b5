"""Signals that end a process, noted by a handler that takes no lock.

Python runs a signal handler in the main thread between two bytecodes, wherever that thread is, even
inside another handler. A handler that takes a lock (``threading.Event.set`` does) deadlocks when it
lands where that lock is already held, and this happens: when a manager dies, Linux sends each of its
children the parent-death signal again every time it hands them on from one of the manager's exiting
threads to the next, so the handlers nest. A subsystem process and a recorder were seen to hang so,
forever. The handler here only stores the signal's name; the main thread acts on it when it next looks.
"""
from __future__ import annotations

import signal


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
