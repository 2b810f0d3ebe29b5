"""``zencosim router``: a Zenoh router for runs whose hosts reach each other only through it.

Hosts behind NAT or in separate networks cannot link directly; each connects out to a router that
they all reach. The manager and the subsystems it spawns stay peers linked with each other and also
connect to the router; a subsystem started by hand that reaches the run only through the router joins
as its client (``subsystems.process.host``). The router forwards between its clients and everyone
else. Routers may connect to each other (``--connect``), so a run can span several networks.
"""
from __future__ import annotations

import signal
import time
from collections.abc import Callable

from zencosim.manager.bus.signals import SignalNote
from zencosim.manager.bus.zenoh_session import (
    SessionError,
    ZenohOptions,
    concrete_endpoint,
    open_session,
    session_config,
)

LOOK_S = 0.1  # how often the main thread looks for a signal


class RouterError(RuntimeError):
    """The router could not start (its address is taken, or not this host's)."""


def serve_router(listen: list[str], connect: list[str], options: ZenohOptions,
                 announce: Callable[[str], None]) -> int:
    """Route until SIGINT or SIGTERM; return the process exit code."""
    listen = [concrete_endpoint(endpoint) for endpoint in listen]
    signals = SignalNote(signal.SIGINT, signal.SIGTERM)
    try:
        session = open_session(session_config(listen, connect, options, mode="router"), listen)
    except SessionError as error:
        raise RouterError(f"cannot start the router: {error}") from None
    with session:
        transport = "lowlatency" if options.lowlatency else "default"
        announce(f"zencosim router {session.zid()} listening on {', '.join(listen)} ({transport} transport); "
                 "Ctrl-C stops it")
        while signals.received is None:
            time.sleep(LOOK_S)
    announce(f"router stopped ({signals.received})")
    return 0
