"""Shared helpers: run a bundled scene with overrides, manage real child processes, write the examples."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
from hypothesis import settings

import zencosim
from zencosim.subsystems.native import CACHE_DIR

REPO = Path(__file__).resolve().parents[1]

# every property test draws the same examples on every run (seeds explicit): a CI run cannot fail on an example
# that the runs before it never drew; a test's own @settings change only what they name
settings.register_profile("derandomized", derandomize=True, database=None)
settings.load_profile("derandomized")


EXAMPLE_MODEL = "zencosim.examples.oscillator:Oscillator"


def pytest_addoption(parser):
    parser.addoption("--model", action="append", default=[], metavar="REF",
                     help="also run the conformance test over this model: package.module:Class or a path to an FMU")


def pytest_configure(config):
    # A shell without job control starts a background job (`pytest … &`) with SIGINT ignored, and an ignored
    # signal stays ignored across exec: every run this suite starts would then ignore the SIGINT that the
    # tests of interruption send it. The suite's processes start as from a terminal: SIGINT acts.
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # the compiled C loops (subsystems.native) are kept in a cache of the session's own, which the processes it
    # starts share, not in the user's
    os.environ[CACHE_DIR] = tempfile.mkdtemp(prefix="zencosim-test-cache-")


def pytest_unconfigure(config):
    shutil.rmtree(os.environ.pop(CACHE_DIR, ""), ignore_errors=True)


def pytest_generate_tests(metafunc):
    if "user_model" in metafunc.fixturenames:
        # without --model: the example user model that ships with zencosim
        metafunc.parametrize("user_model", metafunc.config.getoption("model") or [EXAMPLE_MODEL])


def summary_of(scene_name: str, *overrides: str, bus: str = "inproc", **options) -> dict:
    return zencosim.run(zencosim.load_scene(scene_name, overrides), bus, **options).summary


def record_of(scene_name: str, *overrides: str, bus: str = "inproc"):
    return zencosim.run(zencosim.load_scene(scene_name, overrides), bus).record


def children_of(pid: int) -> list[int]:
    """The child processes of ``pid`` and theirs, parents first (Linux /proc): an in-process run started from the
    command line runs in a child of the process started (``manager.bus.watchdog``), its recorder in a child of that."""
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        children = task / "children"
        if children.exists():
            found += [int(p) for p in children.read_text().split()]
    return found + [grandchild for child in found for grandchild in children_of(child)]


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except FileNotFoundError:
        return ""


@pytest.fixture(scope="module")
def examples(tmp_path_factory) -> Path:
    """The example scenes and FMUs (``zencosim examples``), written and built in a folder of the test module's."""
    if shutil.which("gcc") is None:
        pytest.skip("building the example FMUs needs gcc")
    from zencosim.examples.write import write_examples

    directory = tmp_path_factory.mktemp("examples")
    write_examples(directory)
    return directory


@pytest.fixture
def processes():
    """Start real processes; whatever happens in the test, none of them (or their children) survives it.

    Each starts a process group of its own, which its children join; at the end the whole group is
    killed, so that children orphaned by a killed manager are found too."""
    started: list[subprocess.Popen] = []

    def start(*args: str, prefix: tuple[str, ...] = (), **kwargs) -> subprocess.Popen:
        """``zencosim ARGS``; ``prefix`` runs it through another command that execs it (``ip netns exec NS``)."""
        proc = subprocess.Popen([*prefix, sys.executable, "-m", "zencosim", *args], cwd=REPO,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                                **kwargs)
        started.append(proc)
        return proc

    yield start
    for proc in started:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass  # the group is empty


def read_until(stream, text: str, timeout_s: float) -> list[str]:
    """Lines of ``stream`` up to the first that contains ``text`` (in a thread: readline blocks)."""
    lines: list[str] = []
    found = threading.Event()

    def reader() -> None:
        for line in stream:
            lines.append(line)
            if text in line:
                found.set()
                return

    threading.Thread(target=reader, daemon=True).start()
    if not found.wait(timeout_s):
        raise AssertionError(f"no line with {text!r} within {timeout_s} s; got {lines}")
    return lines


def wait_for(predicate, timeout_s: float, what: str):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


# Starts CPU-bound processes, writes their ids to a file, then becomes the command after it: in the run's session,
# so that Linux's autogroups (one per session) do not shelter the run from them
BUSY_PREFIX = ("import os, subprocess, sys\n"
               "loop = [sys.executable, '-c', 'while True: pass']\n"
               "busy = [subprocess.Popen(loop) for _ in range(int(sys.argv[1]))]\n"
               "open(sys.argv[2], 'w').write(' '.join(str(process.pid) for process in busy))\n"
               "os.execv(sys.argv[3], sys.argv[3:])\n")


def busy_prefix(count: int, pids: Path) -> tuple[str, ...]:
    """A ``processes`` prefix that keeps ``count`` CPU-bound processes running beside the command (their ids in
    ``pids``; end them with ``end_busy``)."""
    return sys.executable, "-c", BUSY_PREFIX, str(count), str(pids)


def end_busy(pids: Path) -> None:
    """Kill the CPU-bound processes ``busy_prefix`` started."""
    busy = wait_for(lambda: pids.exists() and pids.read_text(), 60, "the busy processes' ids")
    for pid in map(int, busy.split()):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
