"""Zenoh sessions and key expressions of a run.

Every run lives under ``zencosim/<run-id>/``: ``<sub>/y`` a subsystem's replies (read by the other
subsystems), ``<sub>/log`` the same replies in batches (read by the manager), ``<sub>/u`` control
from the manager (STOP), ``<sub>/ctl`` a queryable that describes a subsystem, ``<sub>/timing`` one
that reports the timing of its steps at the end, ``<sub>/alive`` and ``manager/alive`` liveliness
tokens (a crashed process is seen at once), ``<sub>/ready`` a token declared once the subsystem is
connected to every other process, ``manager/go`` the start signal, ``manager/run`` a queryable that
lets a subsystem started by hand find the run. Sessions have explicit endpoints, multicast scouting and
gossip off: a run's processes are peers, each linked to the ones it exchanges with, so that a reply
reaches them in one hop; hosts that reach each other only through a Zenoh router (``zencosim router``)
join as its clients (:func:`session_config`).
"""
from __future__ import annotations

import json
import re
import secrets
import socket
import time
from dataclasses import dataclass
from pathlib import Path

import zenoh

from zencosim.manager.bus.security import ZenohSecurity, remove_dictionaries, zenoh_reason

ROOT = "zencosim"
# what a subsystem process says when a STOP on its ``<sub>/u`` ended it; the manager, which knows whether it sent
# one, reads it in the process's log and names a STOP it did not send (``manager.bus.zenoh_bus``)
STOP_RECEIVED = "stopped by a STOP on its control key"


def new_run_id() -> str:
    """A fresh run id: two runs on one network never share keys."""
    return secrets.token_hex(6)


def key(run_id: str, *parts: str) -> str:
    return "/".join((ROOT, run_id) + parts)


TCP_PROTOCOLS = ("tcp", "tls")  # Zenoh link protocols over a TCP port
EVERY_INTERFACE = "0.0.0.0"  # a listening host that is no address to connect to


def endpoint_host(endpoint: str) -> str:
    """The host of a ``tcp/HOST:PORT`` endpoint."""
    return endpoint.split("/", 1)[-1].rpartition(":")[0]


def reachable(endpoint: str, via_host: str) -> str:
    """Where a process connects to ``endpoint``: a process listening on every interface is reached at
    the host through which the connecting process reached the run (``127.0.0.1`` on the same host)."""
    host = endpoint_host(endpoint)
    return endpoint.replace(host, via_host, 1) if host == EVERY_INTERFACE else endpoint


def wait_for_listener(endpoint: str, timeout_s: float) -> None:
    """Block until a ``tcp/`` or ``tls/HOST:PORT`` endpoint accepts TCP connections (Zenoh peers do not reliably
    retry a connect endpoint that was not listening when the session opened)."""
    protocol = endpoint.split("/", 1)[0]
    if protocol not in TCP_PROTOCOLS:
        return
    host, _, port = reachable(endpoint, "127.0.0.1").removeprefix(protocol + "/").rpartition(":")
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection((host.strip("[]"), int(port)), timeout=0.5):
                return
        except OSError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"nothing listens on {endpoint} after {timeout_s:g} s") from None
            time.sleep(0.02)


def concrete_endpoint(endpoint: str) -> str:
    """``tcp/HOST:0`` (or ``tls/``) with a free port chosen now (so that it can be told to others); else unchanged."""
    protocol = endpoint.split("/", 1)[0]
    if protocol in TCP_PROTOCOLS and endpoint.endswith(":0"):
        host = endpoint[len(protocol) + 1:-len(":0")]
        return f"{protocol}/{host}:{free_tcp_port(host.strip('[]'))}"
    return endpoint


LISTEN_PORTS_FROM = 20000  # ports handed out to listen on start here, below the kernel's ephemeral range
_handed_out: set[int] = set()  # ports this process handed out: never twice (the children of one run bind later)


def _ephemeral_low() -> int:
    """The lowest port the kernel gives outgoing connections (Linux ``ip_local_port_range``; 32768 elsewhere)."""
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free right now on ``host`` and stays free for a child to listen on: chosen below
    the kernel's ephemeral range, which outgoing connections draw from (a port the kernel hands out as free
    may be taken by another process's connection before the child binds it: 33 subsystems starting at
    once saw it). At random in that range and not handed out by this process before (the children of a run
    bind theirs only when they start), tried until one binds; the kernel's choice if none does."""
    low = _ephemeral_low()
    for _ in range(64):
        port = secrets.SystemRandom().randrange(LISTEN_PORTS_FROM, max(low, LISTEN_PORTS_FROM + 1))
        if port in _handed_out:
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            try:
                probe.bind((host, port))
            except OSError:
                continue
        _handed_out.add(port)
        return port
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


@dataclass(frozen=True)
class ZenohOptions:
    """Transport settings every process of a run must share.

    ``lowlatency`` selects Zenoh's low-latency unicast transport (QoS off, no batching); it cannot
    fragment, so every message must stay below 64 KiB, which coupling messages do by far. ``security``: the
    credentials and Zenoh configuration file of the run (``manager.bus.security``).
    """

    lowlatency: bool = True
    security: ZenohSecurity = ZenohSecurity()


MODES = ("peer", "client", "router")


def session_config(listen: list[str] = (), connect: list[str] = (), options: ZenohOptions = ZenohOptions(),
                   mode: str = "peer") -> zenoh.Config:
    """A session configuration with explicit endpoints, multicast scouting and gossip off.

    A run's processes are peers: every process connects itself to the ones it exchanges with (Zenoh peers
    do not forward), and to no other. Gossip would have every peer learn of every other through the manager
    and connect to it too: n² links whose simultaneous opening, measured, lost a link in about 1 of 10
    starts of a 9-subsystem chain. A process that reaches the run only through a router is that router's
    client (a Zenoh router forwards between its clients and everyone, not between two peers, which it
    takes to be linked), and ``zencosim router`` is a router; every link of a run has the same transport
    settings (``options``). A Zenoh configuration file of the user's is the base these settings go on, and the
    credentials are added last (``manager.bus.security``)."""
    if mode not in MODES:
        raise ValueError(f"Zenoh mode {mode!r}: expected one of {', '.join(MODES)}")
    config = options.security.base_config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    if options.lowlatency:
        config.insert_json5("transport/unicast/lowlatency", "true")
        config.insert_json5("transport/unicast/qos/enabled", "false")
    options.security.apply(config)
    return config


class SessionError(ValueError):
    """A Zenoh session that does not open with the settings given (exit status 2)."""


class ListenError(SessionError):
    """An endpoint this process cannot listen on (its port is taken, or the address is not this host's)."""


def open_session(config: zenoh.Config, listen: list[str] = ()) -> zenoh.Session:
    """``zenoh.open(config)``, with the reason in one line: a session that cannot listen on ``listen`` raises
    :class:`ListenError` naming the endpoint and the operating system's reason, any other failure (a
    certificate file that a configuration names but that is missing, ...) :class:`SessionError` with
    Zenoh's reason (Zenoh's own message is a Rust trace)."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        text = str(error)
        reason = re.search(r"([A-Za-z][^:\[\]]*?) \(os error \d+\)", text)
        where = re.search(r"listener bound to (\S+?):? \[", text)
        if where is not None or (listen and reason is not None):
            endpoint = where.group(1) if where else ", ".join(listen)
            raise ListenError(f"cannot listen on {endpoint}: "
                              + (reason.group(1).lower() if reason else zenoh_reason(error))) from None
        where = f" listening on {', '.join(listen)}" if listen else ""
        raise SessionError(f"cannot open the Zenoh session{where}: {zenoh_reason(error)}") from None
    finally:
        remove_dictionaries()


def coupling_publisher(session: zenoh.Session, key_expr: str) -> zenoh.Publisher:
    """A publisher for coupling data: sent at once, never dropped, highest priority."""
    return session.declare_publisher(key_expr, express=True, congestion_control=zenoh.CongestionControl.BLOCK,
                                     priority=zenoh.Priority.REAL_TIME)
