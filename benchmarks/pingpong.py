"""Baselines for the distributed benchmark, each against an echo process started here.

* ``zenoh_round_trips(n, official=True)``: zenoh-python's own z_ping/z_pong examples (default
  configuration, CongestionControl.BLOCK, no express; ping waits on a FIFO subscriber, pong echoes
  from its callback), as peers on loopback with multicast scouting off;
* ``zenoh_round_trips(n, official=False)``: the same pattern with the bus's transport settings
  (low-latency transport, express, real-time priority); with ``tls=(ca, cert, key)``, over mutual TLS;
* ``jacobi_lockstep_steps(n)``: the transport floor of a Jacobi macro-step: two processes in lock step,
  each publishing its value for step j from its subscriber callback as soon as it holds the other's
  value for step j-1, with the bus's session and publisher settings (what two subsystem processes do
  over Zenoh, with no arithmetic and no manager);
* ``udp_round_trips(n)``: a raw loopback UDP round trip from Python.
"""
from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import zenoh

from zencosim.manager.bus.children import cpu_time_s
from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.bus.zenoh_session import ZenohOptions, coupling_publisher, free_tcp_port, session_config

PING, PONG = "zencosim/pingpong/ping", "zencosim/pingpong/pong"  # under zencosim/**: what a TLS run's ACL admits
PAYLOAD = bytes(64)  # a STEP of two_mass_damped is 32 + 2 * 8 = 48 bytes, an OUTPUT 56
STEP_VALUE = struct.Struct("<q48x")  # a lock-step message: the step index, padded to an OUTPUT's 56 bytes
WARM_UP = 200  # steps or round trips before timing starts


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
    """Round-trip times [s] of ``n`` ping-pongs after ``WARM_UP`` of warm-up (``tls``: the authority's
    certificate, a certificate and its key, for both ends, with the bus's settings)."""
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
            for _ in range(n + WARM_UP):
                start = time.perf_counter()
                publisher.put(PAYLOAD)
                replies.recv()
                times.append(time.perf_counter() - start)
            return times[WARM_UP:]
        finally:
            child.kill()
            child.wait()


class _LockStep:
    """One side of the lock step: it publishes its value for step j (from the subscriber callback, as a
    subsystem process steps) once it has published step j-1 and holds the other side's value for step
    j-1, up to step ``last``; the times [ns] at which it published each step are kept."""

    def __init__(self, session: zenoh.Session, mine: str, theirs: str, last: int) -> None:
        self.publisher = coupling_publisher(session, mine)
        self.last = last
        self.published: list[int] = []
        self.received = -1  # the other side's newest step (one publisher, one link: in order)
        self.done = threading.Event()
        self._lock = threading.Lock()
        self.subscriber = session.declare_subscriber(theirs, self._on_value)

    def start(self) -> None:
        """Publish step 0 once the other side subscribes."""
        deadline = time.monotonic() + 30
        while not self.publisher.matching_status.matching:
            if time.monotonic() > deadline:
                raise RuntimeError("the other side of the lock step did not start")
            time.sleep(0.01)
        self._advance()

    def _on_value(self, sample: zenoh.Sample) -> None:
        self.received = STEP_VALUE.unpack(bytes(sample.payload))[0]
        self._advance()

    def _advance(self) -> None:
        with self._lock:
            step = len(self.published)
            while step <= self.last and step - 1 <= self.received:
                self.publisher.put(STEP_VALUE.pack(step))
                self.published.append(time.perf_counter_ns())
                step += 1
            if step > self.last:
                self.done.set()


def _lockstep_side(endpoint: str, last: int) -> None:
    with zenoh.open(_config(endpoint, False, official=False)) as session:
        side = _LockStep(session, "zencosim/pingpong/b", "zencosim/pingpong/a", last)
        side.start()
        side.done.wait(600)
        time.sleep(1.0)  # let the other side take the last value


def jacobi_lockstep_steps(n: int) -> list[float]:
    """Times [s] of ``n`` lock-step Jacobi steps (between consecutive publications of one side) after
    ``WARM_UP`` steps, both processes peers on loopback with the bus's settings."""
    return _lockstep(n)[0]


def jacobi_lockstep_cpu(n: int) -> float:
    """CPU time [s] of both lock-step processes together per step (every thread of each: Zenoh's and Python's),
    over ``n`` steps after ``WARM_UP``."""
    return _lockstep(n)[1]


def _lockstep(n: int) -> tuple[list[float], float]:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    last = n + WARM_UP
    with zenoh.open(_config(endpoint, True, official=False)) as session:
        side = _LockStep(session, "zencosim/pingpong/a", "zencosim/pingpong/b", last)
        child = subprocess.Popen([sys.executable, __file__, "lockstep", endpoint, str(last)])
        try:
            side.start()
            while len(side.published) < WARM_UP and not side.done.is_set():
                time.sleep(0.001)
            first, cpu = len(side.published), time.process_time() + cpu_time_s(child.pid)
            if not side.done.wait(600):
                raise RuntimeError("the lock step did not finish within 600 s")
            cpu_per_step = (time.process_time() + cpu_time_s(child.pid) - cpu) / max(len(side.published) - first, 1)
        finally:
            child.kill()
            child.wait()
    published = side.published[WARM_UP:]
    return [(later - earlier) * 1e-9 for earlier, later in zip(published, published[1:])], cpu_per_step


def _udp_echo(port: int) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        while True:
            data, address = sock.recvfrom(2048)
            sock.sendto(data, address)


def udp_round_trips(n: int) -> list[float]:
    """Round-trip times [s] of ``n`` UDP datagrams to an echo process after ``WARM_UP`` of warm-up."""
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
            for _ in range(n + WARM_UP):
                start = time.perf_counter()
                sock.sendto(PAYLOAD, ("127.0.0.1", port))
                sock.recvfrom(2048)
                times.append(time.perf_counter() - start)
            return times[WARM_UP:]
    finally:
        child.kill()
        child.wait()


if __name__ == "__main__":
    if sys.argv[1] == "pong":
        _pong(sys.argv[2], bool(int(sys.argv[3])), json.loads(sys.argv[4]))
    elif sys.argv[1] == "lockstep":
        _lockstep_side(sys.argv[2], int(sys.argv[3]))
    else:
        _udp_echo(int(sys.argv[2]))
