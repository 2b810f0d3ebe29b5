"""Wall-clock timing of the macro-steps as a process released them.

In process the run's own replica reports it; over Zenoh every subsystem process reports the timing
of its own replica (``subsystems.process.host``) and the summary shows each statistic at its worst.
"""
from __future__ import annotations

import numpy as np

from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.scheme.window import read_rows, row_blocks, spilled

# lower edges [ns] of the bins of a long run's step statistics: 1 ns to ~1000 s, each 0.1 % wider than the last
HISTOGRAM_EDGES_NS = np.unique(np.round(np.geomspace(1.0, 1e12, int(np.log(1e12) / np.log(1.001)) + 1)))


def _percentiles_us(values_ns: np.ndarray) -> dict[str, float]:
    """Median, 99th percentile and maximum [µs]: exact for an array in memory; for a long run's spilled array
    (``manager.scheme.window``) read in blocks into a histogram whose bins are 0.1 % wide (``HISTOGRAM_EDGES_NS``),
    so the percentiles are within 0.1 % (and 1 ns) of the exact ones and the maximum is exact."""
    if not spilled(values_ns):
        return {"median": float(np.median(values_ns)) * 1e-3, "p99": float(np.percentile(values_ns, 99)) * 1e-3,
                "max": float(np.max(values_ns)) * 1e-3}
    return _histogram_percentiles_us(block for _, block in row_blocks(values_ns))


def _histogram_percentiles_us(blocks) -> dict[str, float]:
    counts = np.zeros(len(HISTOGRAM_EDGES_NS) + 1, dtype=np.int64)
    highest = -np.inf
    for block in blocks:
        counts += np.bincount(np.searchsorted(HISTOGRAM_EDGES_NS, block, side="right"), minlength=len(counts))
        highest = max(highest, float(np.max(block)))
    cumulative = np.cumsum(counts)
    lower_edges = np.concatenate(([-np.inf], HISTOGRAM_EDGES_NS))

    def percentile(q: float) -> float:
        where = int(np.searchsorted(cumulative, q / 100 * (cumulative[-1] - 1), side="right"))
        return min(max(float(lower_edges[where]), 0.0), highest)

    return {"median": percentile(50) * 1e-3, "p99": percentile(99) * 1e-3, "max": highest * 1e-3}


def step_timing(record: RunRecord) -> dict:
    """Wall-clock statistics of the macro-steps as the process that ran ``record`` released them: time
    between consecutive releases, and in real-time mode lateness (release minus deadline) and missed
    deadlines. Over Zenoh every subsystem reports these of its own replica (``subsystems.process.host``)."""
    timing = {}
    releases = record.send_time_ns
    if len(releases) > 1:
        if spilled(releases):  # a long run's, read in blocks (its steps: differences across blocks)
            per_step = _histogram_percentiles_us(np.diff(read_rows(releases, max(first - 1, 0), first + len(block)))
                                                 for first, block in row_blocks(releases))
        else:
            per_step = _percentiles_us(np.diff(releases))
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
