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
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.certificates import certificate, certificate_authority
from tests.conftest import summary_of
from tests.netns import ip as _ip
from zencosim.manager.bus.zenoh_session import free_tcp_port, reachable

pytestmark = pytest.mark.multiprocess

HOST_ADDRESS, OTHER_ADDRESS = "10.213.77.1", "10.213.77.2"  # RFC 1918, a /30 of the test's own


@pytest.fixture
def other_host(network):
    """A network namespace reachable from here at OTHER_ADDRESS."""
    namespace = network.namespace("h")
    network.link(None, HOST_ADDRESS, namespace, OTHER_ADDRESS)
    return ("ip", "netns", "exec", namespace)


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


ROUTER_A, SIDE_A = "10.213.78.1", "10.213.78.2"  # the router's namespace and host A's, one /30
ROUTER_B, SIDE_B = "10.213.79.1", "10.213.79.2"  # the router's namespace and host B's, another /30


def credentials(protocol: str, directory: Path) -> dict[str, list[str]]:
    """Each process's TLS options (``tls``: certificates of one authority naming the addresses it is reached at),
    or none (``tcp``)."""
    if protocol == "tcp":
        return {"router": [], "a": [], "b": []}
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command to make certificates")
    certificate_authority(directory, "run")
    addresses = {"router": [ROUTER_A, ROUTER_B], "a": ["127.0.0.1"], "b": [SIDE_B]}
    made = {name: certificate(directory, "run", name, ips) for name, ips in addresses.items()}
    return {name: ["--tls-ca", str(directory / "run-ca.pem"), "--tls-cert", str(cert), "--tls-key", str(key)]
            for name, (cert, key) in made.items()}


@pytest.mark.timeout(150)
@pytest.mark.parametrize("protocol", ["tcp", "tls"])
def test_two_hosts_that_reach_each_other_only_through_a_router_run_with_the_in_process_digest(
        processes, network, tmp_path, protocol):
    # host A (the manager, which spawns S1) and host B (S2, started by hand) each reach the router's namespace
    # on a link of their own; the router does not forward IP, so every message between A and B passes the
    # Zenoh router, and S2 joins as its client; with tls, every link is mutual TLS (docs/security.md)
    options = credentials(protocol, tmp_path)
    router_ns, a, b = network.namespace("r"), network.namespace("a"), network.namespace("b")
    network.link(router_ns, ROUTER_A, a, SIDE_A)
    network.link(router_ns, ROUTER_B, b, SIDE_B)
    _ip("netns", "exec", router_ns, "sysctl", "-qw", "net.ipv4.ip_forward=0")
    unreachable = subprocess.run(["ip", "netns", "exec", a, "ip", "route", "get", SIDE_B], capture_output=True, text=True)
    assert unreachable.returncode != 0, "host A must not reach host B directly: " + unreachable.stdout

    def on(namespace: str) -> tuple[str, ...]:
        return ("ip", "netns", "exec", namespace)

    summary = tmp_path / "summary.json"
    router = processes("router", "--listen", f"{protocol}/0.0.0.0:7447", *options["router"], prefix=on(router_ns))
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--quiet", "--connect",
                        f"{protocol}/{ROUTER_A}:7447", "--external", "S2", "--summary", str(summary), *options["a"],
                        prefix=on(a))
    remote = processes("subsystem", "two_mass_damped", "S2", "--connect", f"{protocol}/{ROUTER_B}:7447", *options["b"],
                       prefix=on(b))
    _, manager_err = manager.communicate(timeout=120)
    _, remote_err = remote.communicate(timeout=30)
    assert manager.returncode == 0, manager_err + remote_err
    assert remote.returncode == 0, remote_err
    assert router.poll() is None, "the router ended with the run"
    assert json.loads(summary.read_text())["digest"] == summary_of("two_mass_damped")["digest"]
