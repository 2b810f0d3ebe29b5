"""Will a run's arrays fit? An estimate of what a run allocates, against the memory this machine has available.

A scheme allocates its record up front (``manager.scheme.jacobi``, ``manager.scheme.implicit``): per base
macro-step, every subsystem's outputs at its communication points (float64, ``n_ticks / ratio + 1`` rows), the
residual power and energy of every bond (two float64 per bond), the send time (int64) and, paced, the lateness
(int64). The summary then builds references of the same signals on the same grid (``manager.results.reference``),
and ``--out`` writes tables of them (``manager.results.tables``): ``RESULT_COPIES`` times the record in all.
"""
from __future__ import annotations

import os
from pathlib import Path

RESULT_COPIES = 3  # the record, a reference of the same signals, the result tables
GIB = 2**30


def record_bytes_per_tick(plan) -> float:
    """Bytes the scheme's record holds per base macro-step of ``plan`` (``manager.plan.run_plan.Plan``)."""
    outputs = sum(len(s.outputs) / s.ratio for s in plan.subsystems)
    return 8.0 * (outputs + 2 * len(plan.bonds) + 2)


def run_bytes(plan, n_ticks: int) -> float:
    """Estimated bytes of a run of ``n_ticks`` base macro-steps: record, references and tables."""
    return RESULT_COPIES * record_bytes_per_tick(plan) * (n_ticks + 1)


def available_bytes() -> int | None:
    """Memory available to a new allocation without swapping (Linux ``MemAvailable``; elsewhere the free
    physical pages), None when the system does not say."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def memory_problem(plan, n_ticks: int, duration: float, macro_step: float) -> str | None:
    """Why a run of ``n_ticks`` macro-steps cannot hold its arrays in this machine's memory; None when it can
    (or when the system does not say how much memory is available)."""
    needed = run_bytes(plan, n_ticks)
    available = available_bytes()
    if available is None or needed <= available:
        return None
    return (f"{duration:g} s in macro-steps of {macro_step:g} s is {n_ticks:,} macro-steps, whose arrays (record, "
            f"references, tables) need about {needed / GIB:.3g} GiB; this machine has {available / GIB:.3g} GiB "
            "available: shorten manager.duration or lengthen manager.macro_step")
