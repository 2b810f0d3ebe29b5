"""Fixtures of the manager's tests."""
from __future__ import annotations

import os
import shutil
import subprocess

import pytest

from tests.netns import Network


@pytest.fixture
def network():
    if shutil.which("ip") is None or os.geteuid() != 0:
        pytest.skip("needs root and iproute2 to make network namespaces")
    made = Network()
    try:
        try:
            made.namespace("p")  # can this machine make one?
        except subprocess.CalledProcessError as error:
            pytest.skip(f"cannot make a network namespace here: {error.stderr.strip()}")
        yield made
    finally:
        made.remove()
