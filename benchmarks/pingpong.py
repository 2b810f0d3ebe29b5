"""Baselines for the distributed benchmark: zenoh-python ping-pong and a raw loopback UDP round trip.

Run as a module by bench_runtime.py; each function starts its echo process and returns round-trip
times [s]. The ping-pong mirrors zenoh-python's z_ping/z_pong examples (pong echoes from its
subscriber callback, ping waits on a FIFO subscriber) with the same session configuration as the bus.
"""
from __future__ import annotations

import socket
import subprocess
import sys
import time

import zenoh

from manager.zenoh_session import ZenohOptions, coupling_publisher, free_tcp_port, peer_config

PAYLOAD = bytes(64)  # a STEP message of two_mass_damped is 24 + 2 * 8 = 40 bytes; an OUTPUT 48


def _pong(endpoint: str, lowlatency: bool) -> None:
    with zenoh.open(peer_config(connect=[endpoint], options=ZenohOptions(lowlatency))) as session:
        publisher = coupling_publisher(session, "bench/pong")
        session.declare_subscriber("bench/ping", lambda sample: publisher.put(sample.payload))
        time.sleep(3600)


def zenoh_round_trips(n: int, lowlatency: bool) -> list[float]:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with zenoh.open(peer_config(listen=[endpoint], options=ZenohOptions(lowlatency))) as session:
        publisher = coupling_publisher(session, "bench/ping")
        replies = session.declare_subscriber("bench/pong")
        child = subprocess.Popen([sys.executable, __file__, "pong", endpoint, str(int(lowlatency))])
        try:
            deadline = time.monotonic() + 30
            while not publisher.matching_status.matching:
                if time.monotonic() > deadline:
                    raise RuntimeError("pong did not start")
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
                except (ConnectionRefusedError, TimeoutError, OSError):
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
        _pong(sys.argv[2], bool(int(sys.argv[3])))
    else:
        _udp_echo(int(sys.argv[2]))
