"""Shared helpers: run a bundled scene with overrides, manage real child processes, write the examples."""
from __future__ import annotations

import faulthandler
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


# ---- @pytest.mark.cpu_timeout(cpu_s): a time limit that follows the test's work, not the wall clock --------------
# pytest-timeout's limit is wall time: on a loaded machine (a load of 35–90 on 2 cores) a test doing the same work
# takes twenty times longer and fails. A test marked cpu_timeout instead fails when it and every process it started
# have used more than cpu_s of CPU (the size of its work, which the load hardly changes), or when together they have
# used none for CPU_STALL_S of wall time (a hang: waiting for what never comes). It replaces pytest-timeout's timer
# for that test (setup, call and teardown), through pytest-timeout's own hook.
CPU_STALL_S = 120.0  # 2 cores at a load of 90 still give a process 2 % of one: 2.7 s of CPU in this time
CPU_PROGRESS_S = 0.05  # the CPU time that counts as progress
CPU_LOOK_S = 0.5  # how often the watch looks


def _cpu_with_ended_children_s(pid: int) -> float:
    """User and system time of live process ``pid`` and of its children that ended (utime, stime, cutime, cstime)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return sum(int(f) for f in fields[11:15]) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0  # it ended meanwhile: its time moves to its parent's


def tree_cpu_s() -> float:
    """The CPU time [s] this process and every process it started, live or ended, have used so far."""
    own = os.times()
    return (own.user + own.system + own.children_user + own.children_system
            + sum(_cpu_with_ended_children_s(pid) for pid in children_of(os.getpid())))


class _CpuWatch:
    """Fails the running test (SIGALRM to the main thread) when its CPU budget is spent or it stalls."""

    def __init__(self, cpu_s: float) -> None:
        self.cpu_s, self.reason = cpu_s, None
        self.start = tree_cpu_s()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._watch, name="cpu_timeout", daemon=True)

    def _watch(self) -> None:
        progress_cpu, progress_at = 0.0, time.monotonic()
        while not self.done.wait(CPU_LOOK_S):
            used, now = tree_cpu_s() - self.start, time.monotonic()
            if used - progress_cpu >= CPU_PROGRESS_S:
                progress_cpu, progress_at = used, now
            if used > self.cpu_s:
                self.reason = f"cpu_timeout: the test and its processes used {used:.1f} s of CPU, over {self.cpu_s:g} s"
            elif now - progress_at > CPU_STALL_S:
                self.reason = (f"cpu_timeout: the test and its processes used no CPU for {CPU_STALL_S:g} s "
                               f"(after {used:.1f} s of CPU): hung")
            if self.reason is not None:
                os.kill(os.getpid(), signal.SIGALRM)
                return


@pytest.hookimpl(optionalhook=True)  # pytest-timeout's hook: without that plugin (-p no:timeout), unused
def pytest_timeout_set_timer(item, settings):
    """For a test marked ``cpu_timeout``: the CPU watch instead of pytest-timeout's wall-clock timer."""
    marker = item.get_closest_marker("cpu_timeout")
    if marker is None or threading.current_thread() is not threading.main_thread():
        return None  # pytest-timeout's own timer
    watch = _CpuWatch(float(marker.args[0]))

    def fail(_signum, _frame):
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        pytest.fail(watch.reason, pytrace=False)

    def cancel() -> None:
        watch.done.set()
        watch.thread.join()
        signal.signal(signal.SIGALRM, signal.SIG_DFL)

    signal.signal(signal.SIGALRM, fail)
    item.cancel_timeout = cancel  # what pytest-timeout's cancel hook calls
    watch.thread.start()
    return True
