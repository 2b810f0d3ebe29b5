"""The in-process bus: every message still goes through the wire codec, subsystems are called directly."""
from __future__ import annotations

from typing import Callable, Generator

from manager.endpoint import SubsystemEndpoint
from manager.jacobi import Exchange, RunRecord


def drive_inprocess(scheme: Generator[Exchange, dict[str, bytes], RunRecord],
                    endpoints: dict[str, SubsystemEndpoint],
                    tap: Callable[[str, str, bytes], None] | None = None) -> RunRecord:
    """Run ``scheme`` to completion. A reply is computed when its command is sent and handed back when
    the scheme awaits it; ``tap(subsystem, direction, message)`` sees every message ('u' in, 'y' out)."""
    pending: dict[str, bytes] = {}
    request = next(scheme)
    while True:
        for name, message in request.sends.items():
            reply = endpoints[name].handle(message)
            if tap is not None:
                tap(name, "u", message)
                tap(name, "y", reply)
            pending[name] = reply
        try:
            request = scheme.send({name: pending.pop(name) for name in request.awaits})
        except StopIteration as done:
            return done.value
