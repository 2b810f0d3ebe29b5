"""Baselines for the distributed benchmark, each against an echo process started here.

* ``zenoh_round_trips(n, official=True)``: zenoh-python's own z_ping/z_pong examples (default
  configuration, CongestionControl.BLOCK, no express; ping waits on a FIFO subscriber, pong echoes
  from its callback), as peers on loopback with multicast scouting off;
* ``zenoh_round_trips(n, official=False)``: the same pattern with the bus's transport settings
  (low-latency transport, express, real-time priority); with ``tls=(ca, cert, key)``, over mutual TLS;
* ``udp_round_trips(n)``: a raw loopback UDP round trip from Python.
"""
from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import zenoh

from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.bus.zenoh_session import ZenohOptions, coupling_publisher, free_tcp_port, session_config

PING, PONG = "zencosim/pingpong/ping", "zencosim/pingpong/pong"  # under zencosim/**: what a TLS run's ACL admits
PAYLOAD = bytes(64)  # a STEP of two_mass_damped is 32 + 2 * 8 = 48 bytes, an OUTPUT 56


def _config(endpoint: str, listen: bool, official: bool, tls: tuple[str, str, str] | None = None) -> zenoh.Config:
    if not official:
        security = ZenohSecurity() if tls is None else ZenohSecurity(None, *map(Path, tls))
        return session_config(listen=[endpoint] if listen else [], connect=[] if listen else [endpoint],
                              options=ZenohOptions(True, security))
    config = zenoh.Config()  # the examples' defaults, plus explicit loopback endpoints and no multicast
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints" if listen else "connect/endpoints", json.dumps([endpoint]))
    return config


def _publisher(session: zenoh.Session, key_expr: str, official: bool) -> zenoh.Publisher:
    if official:
        return session.declare_publisher(key_expr, congestion_control=zenoh.CongestionControl.BLOCK)
    return coupling_publisher(session, key_expr)


def _pong(endpoint: str, official: bool, tls: tuple[str, str, str] | None) -> None:
    with zenoh.open(_config(endpoint, False, official, tls)) as session:
        publisher = _publisher(session, PONG, official)
        session.declare_subscriber(PING, lambda sample: publisher.put(sample.payload))
        time.sleep(3600)


def zenoh_round_trips(n: int, official: bool = True, tls: tuple[str, str, str] | None = None) -> list[float]:
    """Round-trip times [s] of ``n`` ping-pongs after 200 of warm-up (``tls``: the authority's certificate, a
    certificate and its key, for both ends, with the bus's settings)."""
    endpoint = f"{'tcp' if tls is None else 'tls'}/127.0.0.1:{free_tcp_port()}"
    with zenoh.open(_config(endpoint, True, official, tls)) as session:
        publisher = _publisher(session, PING, official)
        replies = session.declare_subscriber(PONG)
        child = subprocess.Popen([sys.executable, __file__, "pong", endpoint, str(int(official)), json.dumps(tls)])
        try:
            deadline = time.monotonic() + 30
            while not publisher.matching_status.matching:
                if time.monotonic() > deadline:
                    raise RuntimeError("the pong process did not start")
                time.sleep(0.05)
            times = []
            for _ in range(n + 200):
                start = time.perf_counter()
                publisher.put(PAYLOAD)
                replies.recv()
                times.append(time.perf_counter() - start)
            return times[200:]
        finally:
            child.kill()
            child.wait()


def _udp_echo(port: int) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        while True:
            data, address = sock.recvfrom(2048)
            sock.sendto(data, address)


def udp_round_trips(n: int) -> list[float]:
    """Round-trip times [s] of ``n`` UDP datagrams to an echo process after 200 of warm-up."""
    port = free_tcp_port()
    child = subprocess.Popen([sys.executable, __file__, "udp", str(port)])
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.settimeout(5.0)
            for _ in range(100):  # until the echo process is up
                try:
                    sock.sendto(PAYLOAD, ("127.0.0.1", port))
                    sock.recvfrom(2048)
                    break
                except OSError:
                    time.sleep(0.05)
            times = []
            for _ in range(n + 200):
                start = time.perf_counter()
                sock.sendto(PAYLOAD, ("127.0.0.1", port))
                sock.recvfrom(2048)
                times.append(time.perf_counter() - start)
            return times[200:]
    finally:
        child.kill()
        child.wait()


if __name__ == "__main__":
    if sys.argv[1] == "pong":
        _pong(sys.argv[2], bool(int(sys.argv[3])), json.loads(sys.argv[4]))
    else:
        _udp_echo(int(sys.argv[2]))
