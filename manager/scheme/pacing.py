"""Real-time pacing: release every macro-step at an absolute wall-clock deadline.

Step j is released at ``t_start + j * macro_step``; every process of a Zenoh run paces its replica of
the scheme to the same start time, which the manager announces on the wall clock (Unix time, so
that processes on hosts with synchronised clocks agree on it) and each process converts once to its
monotonic clock, which then paces (the wall clock may be stepped). The loop sleeps until just before the deadline
and spins for the last ``spin_ns`` (a sleeping thread wakes late, and Zenoh latency grows when the
receiving threads have gone idle). Lateness is release time minus deadline; a step released more than
1 % of the macro-step after its deadline missed it (at 1 kHz, 10 µs): its predecessor returned too late,
or the pacing thread was not on a core when the deadline came. The spin itself overshoots by well under
a microsecond, so a step released on time never counts.
"""
from __future__ import annotations

import os
import sys
import threading
import time

import numpy as np

from zencosim.manager.scheme.window import RowWindow, Spill

# how long before a deadline the pacer stops sleeping and spins (measured, docs/realtime.md): a run
# alone in its process spins longer (wake-ups come late on this machine), subsystem processes that
# share the cores with each other and with Zenoh's threads spin less (spinning takes those cores)
SPIN_ALONE_NS = 500_000
SPIN_SHARED_NS = 200_000
MISSED_SLACK = 0.01  # a step released later than this share of the macro-step after its deadline missed it


class ThreadScheduling:
    """The real-time levers of the thread that releases the steps (docs/realtime.md, levers): the
    SCHED_FIFO policy at ``priority`` (1-99; 0: normal scheduling) and affinity to ``cpu`` (None: any).
    Applied once in each thread that paces (over Zenoh the subscriber callback thread steps, so the
    levers reach the thread that does the work, not Zenoh's other threads). Where the system refuses
    (no privilege, not Linux) one warning on stderr names the lever and the reason and the run goes on
    with normal scheduling."""

    def __init__(self, priority: int = 0, cpu: int | None = None, who: str = "zencosim") -> None:
        self.priority, self.cpu, self.who = priority, cpu, who
        self._threads: set[int] = set()
        self.refused: list[str] = []

    def enter(self) -> None:
        """Apply the levers to the calling thread, once."""
        thread = threading.get_ident()
        if thread in self._threads:
            return
        self._threads.add(thread)
        if self.priority:
            self._try(f"SCHED_FIFO priority {self.priority}",
                      lambda: os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority)))
        if self.cpu is not None:
            self._try(f"affinity to CPU {self.cpu}", lambda: os.sched_setaffinity(0, {self.cpu}))

    def _try(self, lever: str, apply) -> None:
        try:
            apply()
        except (OSError, AttributeError) as error:  # AttributeError: a platform without the call
            if lever not in self.refused:
                self.refused.append(lever)
                print(f"{self.who}: real-time lever refused, {lever}: {error}; stepping without it", file=sys.stderr)


class Pacer:
    def __init__(self, macro_step_ns: int, start_ns: int | None = None,
                 spin_ns: int = SPIN_ALONE_NS, scheduling: ThreadScheduling | None = None) -> None:
        self.macro_step_ns = macro_step_ns
        self.scheduling = scheduling
        self.spin_ns = spin_ns
        self.start_ns = start_ns  # on time.perf_counter_ns's clock (CLOCK_MONOTONIC)
        self.missed_after_ns = int(macro_step_ns * MISSED_SLACK)
        self.last_lateness_ns = 0  # of the step released last (the scheme keeps every step's)
        self.missed = 0

    def wait(self, step: int) -> int:
        """Block until step ``step``'s deadline (the first call starts the clock); return the release time
        [ns, time.perf_counter_ns]."""
        if self.scheduling is not None:
            self.scheduling.enter()
        now = time.perf_counter_ns()
        if self.start_ns is None:
            self.start_ns = now
        deadline = self.start_ns + step * self.macro_step_ns
        if now < deadline:
            if deadline - now > self.spin_ns:
                time.sleep((deadline - now - self.spin_ns) * 1e-9)
            while (now := time.perf_counter_ns()) < deadline:
                pass
        self.last_lateness_ns = now - deadline
        if now - deadline > self.missed_after_ns:
            self.missed += 1
        return now


class Releases:
    """When each macro-step of a run was released [ns, time.perf_counter_ns] — paced by ``pacer`` (a real-time
    run), else at once — and, paced, how late against its deadline: a scheme's record of its steps
    (``RunRecord.send_time_ns``, ``lateness_ns``), in windows that spill with a long run (``spill``)."""

    def __init__(self, n_ticks: int, pacer: Pacer | None, spill: Spill | None) -> None:
        self.pacer = pacer
        self.times = RowWindow(n_ticks, None, np.int64, 0, 1, spill, "send-time")
        self.lateness = None if pacer is None else RowWindow(n_ticks, None, np.int64, 0, 1, spill, "lateness")

    def release(self, tick: int) -> int:
        """Release step ``tick`` (paced: at its deadline) and record it; its release time."""
        pacer = self.pacer
        released_ns = time.perf_counter_ns() if pacer is None else pacer.wait(tick)
        self.times.put(tick, released_ns)
        if pacer is not None:
            self.lateness.put(tick, pacer.last_lateness_ns)
        return released_ns

    def finish(self, rows: int | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """The release times and latenesses of the first ``rows`` steps (default: all; lateness None: not paced)."""
        return self.times.finish(rows), None if self.lateness is None else self.lateness.finish(rows)
