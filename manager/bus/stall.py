"""Whether a run that has not advanced is stalled, or only starved of CPU: the clock that every stall limit runs on.

A run's processes wait for one another; when the run has not advanced for a while, the wall time since it last
did says nothing on a machine with more runnable processes than cores (34 processes at load 90 on 2 cores: a
healthy manager or subsystem may not run for 16 s). The :class:`StallClock` counts only the time that is the
processes' own: the wall time since the run last advanced, less the time that its processes waited for a CPU
(Linux: ``run_delay`` of every thread, ``/proc/PID/task/TID/schedstat``, and the whole look for a thread
runnable at both its ends that did not run between; per look, summed over the processes —
a step passes through them in turn, each waiting in its turn — at most the look's wall time). So:

* a process that sleeps waiting for what never comes (a model that hangs) gets nothing taken off: the clock
  runs at wall speed, less what the run's other processes wait for a CPU meanwhile (on a loaded machine their
  brief wake-ups: the hang is named later, once they stop waiting);
* a process starved of CPU waits in the run queue: the clock stands still, and the run waits for it;
* a process in a loop that never answers gets its CPU share: the clock runs at that share, and its own CPU time
  since the run last advanced (``cpu_s``) reaches the limit too: a process that had CPU and made no progress;
* a stopped process (state ``T``/``t``: SIGSTOP, a debugger) gets nothing taken off while it is stopped;
* a process that is gone is the caller's to see (its exit status).

Where ``schedstat`` cannot be read but ``/proc/loadavg`` or ``os.getloadavg`` can (Linux without schedstats,
macOS, the BSDs), a look takes off the share of the wall time that the machine's load left to others:
``1 - min(1, CPUs / load1)``. Where neither can be read, the clock is the wall time. A process's state and CPU time
come from ``/proc/PID/stat``; elsewhere they are unknown (no state, no CPU time: the spinning process is then caught
by the clock alone).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

from zencosim.manager.bus.children import cpu_time_s, stat_fields

STOPPED = ("T", "t")  # /proc/PID/stat states of a stopped process (proc(5))


@dataclass(frozen=True)
class Reading:
    """One process at one moment: its state letter ("" unknown), CPU time [s] (user + system, all threads; None
    unknown), the time [s] its threads have waited for a CPU, summed (None unknown), and its threads that are
    runnable (id, CPU time [ns]): the kernel adds a wait to ``run_delay`` only once it ends, so a thread runnable
    at two looks with no CPU time between them has waited all along."""

    state: str
    cpu_s: float | None
    waited_s: float | None
    runnable: frozenset[tuple[int, int]] = frozenset()


def read_process(pid: int) -> Reading | None:
    """What ``/proc`` says of process ``pid``; None when it is gone (or ``/proc/PID`` is unreadable)."""
    fields = stat_fields(pid)
    if not fields:
        return None if Path("/proc/self/stat").exists() else Reading("", None, None)
    return Reading(fields[0], cpu_time_s(pid, fields), *_threads(pid))


def _threads(pid: int) -> tuple[float | None, frozenset[tuple[int, int]]]:
    """The time [s] process ``pid``'s threads have spent runnable but not running (sum of ``run_delay``, None
    where unreadable), and its runnable threads (id, CPU time [ns])."""
    waited_ns, read, runnable = 0, False, set()
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return None, frozenset()
    for task in tasks:
        try:
            ran_ns, delay_ns = map(int, Path(f"/proc/{pid}/task/{task}/schedstat").read_text().split()[:2])
            state = Path(f"/proc/{pid}/task/{task}/stat").read_text().rpartition(")")[2].split()[0]
        except (OSError, IndexError, ValueError):
            continue  # a thread that ended meanwhile, or no schedstat
        waited_ns, read = waited_ns + delay_ns, True
        if state == "R":
            runnable.add((int(task), ran_ns))
    return (waited_ns * 1e-9 if read else None), frozenset(runnable)


def load1() -> float:
    """The machine's load, averaged over the last minute (0 where unknown)."""
    try:
        return os.getloadavg()[0]
    except (OSError, AttributeError):
        return 0.0


def machine_share() -> float:
    """The share of a CPU a runnable process gets, as the load says: ``min(1, CPUs / load1)`` (1 where unknown)."""
    load = load1()
    return min(1.0, (os.cpu_count() or 1) / load) if load > 0 else 1.0


class StallClock:
    """The time a run has not advanced, less the time its processes waited for a CPU (see the module text).

    ``restart(now)`` when the run advances; ``look(now, pids)`` now and then while it does not (every look reads
    each process's ``/proc`` entries: look at most a few times a second). ``read`` and ``share`` are
    :func:`read_process` and :func:`machine_share` unless a test feeds its own."""

    def __init__(self, read: Callable[[int], Reading | None] = read_process,
                 share: Callable[[], float] = machine_share) -> None:
        self.read, self.share = read, share
        self.restart(0.0)

    def restart(self, now: float) -> None:
        self.last = now
        self.stalled_s = 0.0  # the clock [s]
        self.excused_s = 0.0  # the wall time taken off it: the processes waited for a CPU
        self.first: dict[str, Reading] = {}  # each process's reading at the first look since the restart
        self.latest: dict[str, Reading | None] = {}

    def look(self, now: float, pids: Mapping[str, int]) -> None:
        """Advance the clock to ``now``, reading processes ``pids`` (name: pid)."""
        wall_s, self.last = max(0.0, now - self.last), now
        readings = {name: self.read(pid) for name, pid in pids.items()}
        excused_s = self._excused_s(wall_s, readings)
        self.stalled_s += wall_s - excused_s
        self.excused_s += excused_s
        for name, reading in readings.items():
            if reading is not None:
                self.first.setdefault(name, reading)
        self.latest = readings

    def _excused_s(self, wall_s: float, readings: Mapping[str, Reading | None]) -> float:
        """The part of ``wall_s`` the processes spent waiting for a CPU: none while one is stopped; else their
        waits summed (schedstat: a step passes through the processes in turn, each waiting for a CPU in its turn),
        at most ``wall_s``; or the load's share where no process's waits can be read."""
        present = {name: r for name, r in readings.items() if r is not None}
        if any(r.state in STOPPED for r in present.values()):
            return 0.0
        waits = [r.waited_s - previous.waited_s + wall_s * len(r.runnable & previous.runnable)
                 for name, r in present.items()
                 if r.waited_s is not None and (previous := self.latest.get(name)) is not None
                 and previous.waited_s is not None]
        if waits:
            return min(wall_s, max(0.0, sum(waits)))
        if any(r.waited_s is not None for r in present.values()):
            return 0.0  # the first look at these processes: nothing to compare with yet
        return wall_s * (1.0 - self.share())

    def cpu_s(self, name: str) -> float:
        """The CPU time [s] process ``name`` used between the first look since the restart and the latest (0
        where unknown)."""
        first, latest = self.first.get(name), self.latest.get(name)
        if first is None or latest is None or first.cpu_s is None or latest.cpu_s is None:
            return 0.0
        return latest.cpu_s - first.cpu_s

    def stopped(self) -> list[str]:
        """The processes stopped at the latest look (state T or t)."""
        return [name for name, r in self.latest.items() if r is not None and r.state in STOPPED]

    def verdict(self, limit_s: float, names: list[str]) -> tuple[str, str] | None:
        """Why the run fails now, as (process, reason), or None while it waits: a process of ``names`` that used
        ``limit_s`` of CPU time since the run last advanced (it had CPU, and made no progress); else, when the
        clock has reached ``limit_s``, one that is stopped, else the first of ``names`` (``"stalled"``: the
        caller names it)."""
        spinning = [name for name in names if self.cpu_s(name) >= limit_s]
        if spinning:
            return spinning[0], (f"its process used {self.cpu_s(spinning[0]):.1f} s of CPU time since the run last "
                                 "advanced, and answered nothing")
        if self.stalled_s < limit_s:
            return None
        stopped = [name for name in self.stopped() if name in names]
        if stopped:
            return stopped[0], "stopped"
        return (names[0] if names else ""), "stalled"
