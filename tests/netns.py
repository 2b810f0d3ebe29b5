"""Network namespaces for tests that need hosts of their own: veth pairs on private /30s, removed at the end.

Needs CAP_NET_ADMIN (root) and ``ip``; the ``network`` fixture (tests/manager/conftest.py) skips a test otherwise.
"""
from __future__ import annotations

import os
import subprocess


def ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=10)


class Network:
    """Network namespaces joined by veth pairs on /30s of the test's own; all removed by :meth:`remove`."""

    def __init__(self) -> None:
        self.namespaces: list[str] = []
        self.links: list[str] = []  # veth pairs with an end in this namespace (the others go with theirs)
        self.made = 0

    def namespace(self, tag: str) -> str:
        name = f"zc{os.getpid()}{tag}"
        ip("netns", "add", name)
        self.namespaces.append(name)
        ip("-n", name, "link", "set", "lo", "up")
        return name

    def link(self, a: str | None, a_address: str, b: str, b_address: str) -> None:
        """A veth pair from namespace ``a`` (None: this one) to ``b``, addressed ``a_address`` and ``b_address``."""
        self.made += 1
        veth = f"zv{os.getpid() % 10000}n{self.made}"
        here = () if a is None else ("-n", a)
        ip(*here, "link", "add", veth, "type", "veth", "peer", "name", veth + "b", "netns", b)
        if a is None:
            self.links.append(veth)
        ip(*here, "addr", "add", f"{a_address}/30", "dev", veth)
        ip(*here, "link", "set", veth, "up")
        ip("-n", b, "addr", "add", f"{b_address}/30", "dev", veth + "b")
        ip("-n", b, "link", "set", veth + "b", "up")

    def remove(self) -> None:
        for veth in self.links:
            subprocess.run(["ip", "link", "del", veth], capture_output=True, timeout=10)
        for name in self.namespaces:
            subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=10)
