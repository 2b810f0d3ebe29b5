"""A stall is a stall: a run waits for processes starved of CPU and fails for one that is stopped, hangs,
or had CPU and answered nothing (manager.bus.stall).

The decision is tested on /proc-like readings fed to the clock (a starved process cannot be simulated reliably on a
busy machine); real processes show that a stopped one is read as stopped and that a starved run completes.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys

import pytest

from tests.conftest import busy_prefix, children_of, end_busy, read_until, summary_of, wait_for
from zencosim.manager.bus.stall import Reading, StallClock, read_process

LIMIT_S = 10.0
STARVED_S = 3.0  # [s] of wall time the real run below is starved of CPU
DURATION_S = 5.0  # [s] its simulated time: 5,000 steps, more than it takes in STARVED_S at the lowest priority


def _clock(trace: dict[str, list[Reading]], share: float = 1.0, look_s: float = 0.5) -> StallClock:
    """A clock fed, at looks ``look_s`` apart, the readings of ``trace`` (name: one reading per look)."""
    looks = len(next(iter(trace.values())))
    at = {"look": 0}
    clock = StallClock(read=lambda pid: trace[pid][at["look"]], share=lambda: share)
    clock.restart(0.0)
    for look in range(looks):
        at["look"] = look
        clock.look(look * look_s, {name: name for name in trace})
    return clock


def _process(state: str, cpu_per_look_s: float, waited_per_look_s: float | None, looks: int) -> list[Reading]:
    return [Reading(state, 1.0 + i * cpu_per_look_s, None if waited_per_look_s is None else 5.0 + i * waited_per_look_s)
            for i in range(looks)]


def test_a_process_starved_of_cpu_is_waited_for_however_long():
    """Runnable, its CPU time still, its waits for a CPU the whole look: 1,000 s without an answer count nothing."""
    clock = _clock({"S1": _process("R", 0.0, 0.5, 2001), "S2": _process("S", 0.0, 0.0, 2001)})
    assert clock.stalled_s == 0.0 and clock.excused_s == pytest.approx(1000.0)
    assert clock.verdict(LIMIT_S, ["S1", "S2"]) is None


def test_a_wait_the_kernel_has_not_yet_added_to_run_delay_counts_and_waits_in_turn_add_up():
    """run_delay grows only when a wait ends: a thread runnable at two looks that did not run between them waited
    all along. And a step that passes through S1 then S2, each waiting half a look in its turn, waited the whole."""
    queued = frozenset({(4242, 7_000_000)})
    still = _clock({"S1": [Reading("R", 1.0, 5.0, queued)] * 21})
    assert still.stalled_s == 0.0 and still.verdict(LIMIT_S, ["S1"]) is None
    ran = _clock({"S1": [Reading("R", 1.0, 5.0, frozenset({(4242, 7_000_000 + i)})) for i in range(21)]})
    assert ran.stalled_s == pytest.approx(LIMIT_S)  # it ran between looks: not a pending wait
    in_turn = _clock({"S1": _process("S", 0.0, 0.25, 21), "S2": _process("S", 0.0, 0.25, 21)})
    assert in_turn.stalled_s == pytest.approx(0.0) and in_turn.excused_s == pytest.approx(LIMIT_S)


def test_a_process_that_sleeps_without_answering_fails_at_the_limit_in_wall_time():
    """A model that hangs in a sleep: no CPU used, no wait for a CPU: the clock is the wall time."""
    clock = _clock({"S1": _process("S", 0.0, 0.0, 21), "S2": _process("S", 0.0, 0.0, 21)})
    assert clock.stalled_s == pytest.approx(LIMIT_S)
    assert clock.verdict(LIMIT_S, ["S1", "S2"]) == ("S1", "stalled")
    assert _clock({"S1": _process("S", 0.0, 0.0, 20)}).verdict(LIMIT_S, ["S1"]) is None  # 9.5 s: not yet


def test_a_process_that_has_cpu_and_answers_nothing_fails_by_its_cpu_time():
    """A loop that never answers on a machine that leaves it 5 % of a core: the clock runs at 5 %, and the process
    is named once it has used the limit in CPU time (200 s of wall time), not before."""
    spinning = {"S1": _process("R", 0.025, 0.475, 401), "S2": _process("S", 0.0, 0.0, 401)}
    clock = _clock(spinning)
    assert clock.stalled_s == pytest.approx(0.05 * 200.0) and clock.cpu_s("S1") == pytest.approx(LIMIT_S)
    name, reason = clock.verdict(LIMIT_S, ["S1", "S2"])
    assert name == "S1" and reason.startswith("its process used 10.0 s of CPU time since the run last advanced")
    assert _clock({name: readings[:390] for name, readings in spinning.items()}).verdict(LIMIT_S, ["S1", "S2"]) is None


def test_a_stopped_process_fails_at_the_limit_in_wall_time_even_beside_starved_ones():
    clock = _clock({"S1": _process("T", 0.0, 0.0, 21), "S2": _process("R", 0.0, 0.5, 21)})
    assert clock.stalled_s == pytest.approx(LIMIT_S) and clock.verdict(LIMIT_S, ["S1", "S2"]) == ("S1", "stopped")


def test_without_schedstat_the_load_gives_the_share_of_the_wall_time_that_counts():
    """No /proc/PID/task/*/schedstat (another kernel, macOS): a load of 40 on 2 CPUs counts 5 % of the wall time."""
    clock = _clock({"S1": _process("", 0.0, None, 201)}, share=2 / 40)
    assert clock.stalled_s == pytest.approx(0.05 * 100.0) and clock.verdict(LIMIT_S, ["S1"]) is None


@pytest.mark.multiprocess
def test_a_real_process_stopped_with_sigstop_is_read_as_stopped_and_one_gone_as_gone():
    if not os.path.exists("/proc/self/stat"):
        pytest.skip("no /proc: a process's state cannot be read here")
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        clock = StallClock()
        clock.restart(0.0)
        os.kill(child.pid, signal.SIGSTOP)
        os.waitpid(child.pid, os.WUNTRACED)  # returns once it is stopped: the signal is delivered asynchronously
        clock.look(0.0, {"S1": child.pid})
        clock.look(LIMIT_S, {"S1": child.pid})
        assert clock.stopped() == ["S1"] and clock.verdict(LIMIT_S, ["S1"]) == ("S1", "stopped")
        assert read_process(os.getpid()).waited_s is not None  # schedstat read: waits for a CPU are measured
    finally:
        child.kill()
        child.wait()
    assert read_process(child.pid) is None


def _at_idle_priority(pid: int) -> None:
    """Every thread of process ``pid`` at the idle scheduling policy (SCHED_IDLE): a CPU-bound process beside it at
    normal priority, in the same session, leaves it almost no CPU."""
    for thread in os.listdir(f"/proc/{pid}/task"):
        try:
            os.sched_setscheduler(int(thread), os.SCHED_IDLE, os.sched_param(0))
        except (ProcessLookupError, PermissionError):
            pass  # a thread that ended meanwhile


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(240)
def test_a_run_whose_subsystems_are_starved_of_cpu_waits_says_so_and_completes(processes, tmp_path):
    """The subsystem processes at idle priority beside three CPU-bound processes per core (in the run's session,
    held stopped until the run steps, so that they do not slow its start), for STARVED_S, with manager.timeout =
    0.2 s: the manager, at normal priority, looks at a run that does not advance for far longer than 0.2 s (judged
    by wall time, the run failed: ``subsystem S1 (or S2): did not answer within the timeout of 0.2 s``, as chain 9
    did at load 37),
    but its subsystems wait in the run queue: it says that it waits for them, and the run completes with the
    in-process digest. No wall-clock assertion."""
    if not hasattr(os, "SCHED_IDLE") or not os.path.exists("/proc/self/task"):
        pytest.skip("needs Linux's SCHED_IDLE and /proc")
    summary, pids = tmp_path / "summary.json", tmp_path / "busy.pids"
    overrides = (f"manager.duration={DURATION_S}", "manager.timeout=0.2")
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--summary", str(summary),
                        *(word for o in overrides for word in ("--set", o)),
                        prefix=busy_prefix(3 * len(os.sched_getaffinity(0)), pids))
    busy = [int(pid) for pid in wait_for(lambda: pids.exists() and pids.read_text(), 60, "the busy ids").split()]
    try:
        for pid in busy:
            os.kill(pid, signal.SIGSTOP)
        lines = read_until(manager.stderr, "starting", 120)
        for pid in children_of(manager.pid):
            if pid not in busy:
                _at_idle_priority(pid)
        for pid in busy:
            os.kill(pid, signal.SIGCONT)
        try:
            _, rest = manager.communicate(timeout=STARVED_S)  # ends early only if the run failed
        except subprocess.TimeoutExpired:
            end_busy(pids)
            _, rest = manager.communicate(timeout=200)
    finally:
        end_busy(pids)
    stderr = "".join(lines) + rest
    assert manager.returncode == 0, stderr
    assert re.search(r"no step for \d+\.\d s; \d+\.\d s of it its processes waited for a CPU", stderr), stderr
    digest = summary_of("two_mass_damped", f"manager.duration={DURATION_S}")["digest"]
    assert json.loads(summary.read_text())["digest"] == digest
