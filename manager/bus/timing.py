"""Wall-clock timing of the macro-steps as a process released them.

In process the run's own replica reports it; over Zenoh every subsystem process reports the timing
of its own replica (``subsystems.process.host``) and the summary shows each statistic at its worst.
"""
from __future__ import annotations

import numpy as np

from zencosim.manager.scheme.base import RunRecord


def _percentiles_us(values_ns: np.ndarray) -> dict[str, float]:
    return {"median": float(np.median(values_ns)) * 1e-3, "p99": float(np.percentile(values_ns, 99)) * 1e-3,
            "max": float(np.max(values_ns)) * 1e-3}


def step_timing(record: RunRecord) -> dict:
    """Wall-clock statistics of the macro-steps as the process that ran ``record`` released them: time
    between consecutive releases, and in real-time mode lateness (release minus deadline) and missed
    deadlines. Over Zenoh every subsystem reports these of its own replica (``subsystems.process.host``)."""
    timing = {}
    steps = np.diff(record.send_time_ns)
    if len(steps):
        per_step = _percentiles_us(steps)
        timing.update(step_us_median=per_step["median"], step_us_p99=per_step["p99"], step_us_max=per_step["max"])
    if record.lateness_ns is not None:
        late = _percentiles_us(record.lateness_ns)
        timing.update(lateness_us_median=late["median"], lateness_us_p99=late["p99"], lateness_us_max=late["max"],
                      missed_deadlines=record.missed_deadlines, paced_steps=len(record.lateness_ns), realtime=True)
    return timing


def worst_timing(reports: dict[str, dict]) -> dict:
    """The subsystems' step timings combined: each statistic at its worst (largest) over the subsystems
    (``replies_received``: the most replies a process took from the network; ``cpu_s``: the most CPU time a
    process used while it stepped)."""
    keys = {k for report in reports.values() for k in report}
    return {k: (True if k == "realtime" else max(report[k] for report in reports.values() if k in report))
            for k in sorted(keys)}


def run_timing(record: RunRecord, wall_s: float) -> dict:
    """The timing of a run as the summary gives it (docs/summary.md): wall time, steps per second and the
    step statistics, over Zenoh as the subsystems released the steps (the worst, and each one's)."""
    timing = {"wall_s": wall_s, "steps_per_s": len(record.send_time_ns) / wall_s}  # the macro-steps executed
    if record.reported_timing:
        timing.update(worst_timing(record.reported_timing), subsystems=record.reported_timing,
                      manager_cpu_s=record.manager_cpu_s)
    else:
        timing.update(step_timing(record))
    return timing
