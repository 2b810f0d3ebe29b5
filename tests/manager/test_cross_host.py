"""A run across hosts: one subsystem in a network namespace of its own, the README's commands.

The test makes a second "host" — a network namespace joined to this one by a veth pair on a private
/30 — and starts the manager as the README says (``--listen tcp/0.0.0.0:PORT --external S2``), so
that it spawns S1 here, and S2 by hand inside the namespace, connecting to the manager's address on
the veth link. S2 cannot reach this host's loopback: the run only completes if S2 connects to S1 at
an address of this host it can reach (``manager.bus.zenoh_session.reachable``). Traffic stays on the
veth pair and loopback. Needs CAP_NET_ADMIN (root) and ``ip``; skipped otherwise.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess

import pytest

from tests.conftest import summary_of
from zencosim.manager.bus.zenoh_session import free_tcp_port, reachable

pytestmark = pytest.mark.multiprocess

HOST_ADDRESS, OTHER_ADDRESS = "10.213.77.1", "10.213.77.2"  # RFC 1918, a /30 of the test's own


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=10)


@pytest.fixture
def other_host():
    """A network namespace reachable from here at OTHER_ADDRESS; removed (with its veth pair) at the end."""
    if shutil.which("ip") is None or os.geteuid() != 0:
        pytest.skip("needs root and iproute2 to make a network namespace")
    namespace, veth = f"zc{os.getpid()}", f"zcv{os.getpid() % 100000}"
    try:
        _ip("netns", "add", namespace)
    except subprocess.CalledProcessError as error:
        pytest.skip(f"cannot make a network namespace here: {error.stderr.strip()}")
    try:
        _ip("link", "add", veth, "type", "veth", "peer", "name", veth + "b")
        _ip("link", "set", veth + "b", "netns", namespace)
        _ip("addr", "add", f"{HOST_ADDRESS}/30", "dev", veth)
        _ip("link", "set", veth, "up")
        _ip("-n", namespace, "addr", "add", f"{OTHER_ADDRESS}/30", "dev", veth + "b")
        _ip("-n", namespace, "link", "set", veth + "b", "up")
        _ip("-n", namespace, "link", "set", "lo", "up")
        yield ("ip", "netns", "exec", namespace)
    finally:
        subprocess.run(["ip", "link", "del", veth], capture_output=True, timeout=10)
        subprocess.run(["ip", "netns", "del", namespace], capture_output=True, timeout=10)


def test_an_endpoint_on_every_interface_is_reached_through_the_run_s_host():
    assert reachable("tcp/0.0.0.0:7448", "192.0.2.10") == "tcp/192.0.2.10:7448"
    assert reachable("tcp/192.0.2.11:7448", "192.0.2.10") == "tcp/192.0.2.11:7448"
    assert reachable("tcp/127.0.0.1:7448", "192.0.2.10") == "tcp/127.0.0.1:7448"


@pytest.mark.timeout(120)
def test_a_subsystem_on_another_host_joins_and_the_digest_is_the_in_process_one(processes, other_host, tmp_path):
    port = free_tcp_port()
    summary = tmp_path / "summary.json"
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--quiet", "--listen", f"tcp/0.0.0.0:{port}",
                        "--external", "S2", "--summary", str(summary))
    remote = processes("subsystem", "two_mass_damped", "S2", "--connect", f"tcp/{HOST_ADDRESS}:{port}",
                       "--listen", f"tcp/{OTHER_ADDRESS}:0", prefix=other_host)
    _, manager_err = manager.communicate(timeout=90)
    _, remote_err = remote.communicate(timeout=30)
    assert manager.returncode == 0, manager_err + remote_err
    assert remote.returncode == 0, remote_err
    assert json.loads(summary.read_text())["digest"] == summary_of("two_mass_damped")["digest"]
