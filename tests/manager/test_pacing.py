"""Real-time pacing facts that hold however busy the machine is (the figures are benchmarks/bench_realtime.py's).

A paced step is never released before its deadline, every step's release is accounted as deadline plus
lateness, and the missed deadlines are exactly the steps released more than 1 % of the macro-step late
(manager/scheme/pacing.py). A pacer that released early, skipped a step, kept the wrong clock or
counted misses differently fails these; a busy machine only makes the lateness larger.
"""
import os
import threading
import time

import numpy as np
import pytest

import zencosim
from zencosim.manager.scheme.pacing import MISSED_SLACK, Pacer, ThreadScheduling


def _check_accounted(send_time_ns: np.ndarray, lateness_ns: np.ndarray, missed: int, step_ns: int) -> None:
    steps = np.arange(len(send_time_ns), dtype=np.int64)
    assert len(lateness_ns) == len(send_time_ns)
    assert (lateness_ns >= 0).all(), "a step was released before its deadline"
    start_ns = send_time_ns[0] - lateness_ns[0]
    # release = start + j * H + lateness, to the nanosecond
    assert np.array_equal(send_time_ns - lateness_ns - start_ns, steps * step_ns)
    assert missed == np.count_nonzero(lateness_ns > step_ns * MISSED_SLACK)


@pytest.mark.parametrize("scene, overrides", [
    ("two_mass_damped", ["manager.duration=0.3"]),
    ("constrained_two_mass", ["manager.duration=0.1"]),  # the implicit scheme paces too
])
def test_every_step_of_a_realtime_run_is_paced_and_accounted(scene, overrides):
    result = zencosim.run(zencosim.load_scene(scene, overrides), realtime=True)
    record = result.record
    assert len(record.lateness_ns) == record.plan.n_ticks
    _check_accounted(record.send_time_ns, record.lateness_ns, record.missed_deadlines, record.plan.base_step_ns)
    # the wall clock covered the simulated time: the last step went out (n - 1) steps after the first
    assert result.summary["timing"]["wall_s"] >= (record.plan.n_ticks - 1) * record.plan.base_step_ns * 1e-9
    assert result.summary["timing"]["missed_deadlines"] == record.missed_deadlines
    assert result.summary["timing"]["paced_steps"] == record.plan.n_ticks


def test_a_step_whose_predecessor_overran_is_released_at_once_and_missed():
    step_ns = 1_000_000
    pacer = Pacer(step_ns)
    released = [pacer.wait(0)]
    lateness = [pacer.last_lateness_ns]
    released.append(pacer.wait(1))
    lateness.append(pacer.last_lateness_ns)
    busy_until = released[-1] + 3 * step_ns // 2  # step 1 takes 1.5 steps: step 2 is 0.5 steps late
    while time.perf_counter_ns() < busy_until:
        pass
    released.append(pacer.wait(2))
    lateness.append(pacer.last_lateness_ns)
    _check_accounted(np.array(released), np.array(lateness), pacer.missed, step_ns)
    assert lateness[2] >= step_ns // 2 and pacer.missed >= 1


def _in_a_thread(action):
    """Run ``action`` in a new thread (the levers are per thread) and return what it returns."""
    found = []
    thread = threading.Thread(target=lambda: found.append(action()))
    thread.start()
    thread.join()
    return found[0]


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling calls")
def test_the_levers_reach_the_pacing_thread_or_are_refused_with_a_warning(capsys):
    def paced():
        scheduling = ThreadScheduling(priority=10, cpu=0, who="subsystem S1")
        Pacer(1_000_000, scheduling=scheduling).wait(0)
        return os.sched_getscheduler(0), os.sched_getaffinity(0), scheduling.refused

    policy, cpus, refused = _in_a_thread(paced)
    assert cpus == {0}  # affinity needs no privilege
    if "SCHED_FIFO priority 10" in refused:  # without the privilege: normal scheduling and one warning
        assert policy == os.SCHED_OTHER
        assert "subsystem S1: real-time lever refused, SCHED_FIFO priority 10" in capsys.readouterr().err
    else:
        assert policy == os.SCHED_FIFO
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the test's own thread is untouched

    def refused_priority():  # a priority the kernel refuses whatever the privilege: the fallback path
        scheduling = ThreadScheduling(priority=100, who="subsystem S2")
        scheduling.enter()
        scheduling.enter()  # once per thread: one warning
        return os.sched_getscheduler(0), scheduling.refused

    policy, refused = _in_a_thread(refused_priority)
    assert (policy, refused) == (os.SCHED_OTHER, ["SCHED_FIFO priority 100"])
    assert capsys.readouterr().err.count("subsystem S2: real-time lever refused, SCHED_FIFO priority 100") == 1
