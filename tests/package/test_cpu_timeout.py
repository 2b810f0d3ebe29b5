"""``@pytest.mark.cpu_timeout`` (tests/conftest.py): a test's limit that follows its work, not the wall clock. A test
that waits past its wall-clock timeout while using little CPU passes; one whose child process burns CPU past the
budget fails, its child ended, with the reason. Each in a pytest of its own, with the suite's configuration."""
from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import REPO

CASES = '''
import subprocess, sys, time
import pytest

@pytest.mark.timeout(1)
@pytest.mark.cpu_timeout(30)
def test_waits_longer_than_its_wall_clock_timeout():
    time.sleep(1.5)

@pytest.mark.cpu_timeout(0.5)
def test_burns_cpu_in_a_child():
    subprocess.run([sys.executable, "-c", "while True: pass"])
'''


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_cpu_timeout_replaces_the_wall_clock_limit_and_counts_the_children(tmp_path):
    (tmp_path / "test_cases.py").write_text(CASES)
    run = subprocess.run([sys.executable, "-m", "pytest", "-p", "tests.conftest", "-c", str(REPO / "pyproject.toml"),
                          "--rootdir", str(REPO), "-p", "no:cacheprovider", "-q", "-rA", str(tmp_path)],
                         cwd=REPO, capture_output=True, text=True, timeout=120)
    assert "1 failed, 1 passed" in run.stdout, run.stdout[-3000:]
    assert "PASSED test_cases.py::test_waits_longer_than_its_wall_clock_timeout" in run.stdout
    assert "FAILED test_cases.py::test_burns_cpu_in_a_child" in run.stdout
    assert "cpu_timeout: the test and its processes used" in run.stdout and "of CPU, over 0.5 s" in run.stdout
