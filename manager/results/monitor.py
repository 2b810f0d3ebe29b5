"""Monitoring of the residual power: spikes that mark unreliable intervals (paper 002 §3.1, Fig. 37).

The paper reads a co-simulation as unreliable where the residual power δP of a bond changes suddenly
("the presence of sudden changes in the indicator can be a symptom of unstable behaviour"). The
detector makes that reading mechanical, per bond and causally (it uses only past points, so the
manager could run it while stepping):

* the *baseline* at a communication point is the median of |δP| over the preceding ``window``
  seconds, over the points that were not themselves flagged (a burst does not raise its own
  baseline, so the whole burst is flagged, not only its onset);
* a point is flagged when ``|δP| > threshold × baseline``; no point is flagged before a full window
  of history exists (a run that starts at rest has no meaningful baseline at first);
* flagged points closer than ``merge_gap`` seconds form one interval.

The parameters are the scene's ``[manager.spikes]``. Defaults: a 2 s window (longer than the beats
of the four-mass chain's residual power, whose quiet phases make a 1 s baseline flag the next beat)
and a threshold of 50: over the regular runs of every bundled scene the largest ratio of |δP| to its
baseline is 17 (two_mass_chirp passing resonance), over the 11.5 ms hydraulic crane 1.7·10³
(docs/numerics.md, "Residual-power spikes").
"""
from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

import numpy as np

from zencosim.manager.scheme.window import row_blocks


@dataclass(frozen=True)
class SpikeInterval:
    """An interval of flagged residual power on one bond."""

    start: float  # [s] first flagged point
    end: float  # [s] last flagged point
    peak_time: float  # [s]
    peak: float  # [W] δP at the largest |δP| of the interval
    points: int  # flagged communication points in the interval

    def as_dict(self) -> dict:
        return {"start": self.start, "end": self.end, "peak_time": self.peak_time, "peak_w": self.peak,
                "points": self.points}


class SpikeMonitor:
    """The detector of the module text, fed a bond's δP block by block, in time order."""

    def __init__(self, window: float, threshold: float, merge_gap: float) -> None:
        self.window, self.threshold, self.merge_gap = window, threshold, merge_gap
        self.times: deque[float] = deque()  # the times of the unflagged points in the window
        self.magnitudes: deque[float] = deque()  # and their |δP|
        self.ordered: list[float] = []  # the same magnitudes, sorted (a running median in O(log n) + memmove)
        self.start: float | None = None
        self.intervals: list[SpikeInterval] = []
        self.open: list | None = None  # the interval being grown: [start, end, peak time, peak, points]

    def flags(self, t: np.ndarray, p_res: np.ndarray) -> np.ndarray:
        """Boolean mask of the flagged points among the next points ``t`` [s], ``p_res`` [W]."""
        flagged = np.zeros(len(t), dtype=bool)
        times, magnitudes, ordered = self.times, self.magnitudes, self.ordered
        window, threshold = self.window, self.threshold
        if self.start is None and len(t):
            self.start = float(t[0])
        start = self.start
        insort, position = bisect.insort, bisect.bisect_left
        for i, (time, magnitude) in enumerate(zip(t.tolist(), np.abs(p_res).tolist())):
            oldest = time - window
            while times and times[0] < oldest:
                times.popleft()
                del ordered[position(ordered, magnitudes.popleft())]
            if time - start >= window and ordered:  # a full window of history
                middle = len(ordered) // 2
                baseline = ordered[middle] if len(ordered) % 2 else 0.5 * (ordered[middle - 1] + ordered[middle])
                if magnitude > threshold * baseline:
                    flagged[i] = True
                    continue
            times.append(time)
            magnitudes.append(magnitude)
            insort(ordered, magnitude)
        return flagged

    def add(self, t: np.ndarray, p_res: np.ndarray) -> None:
        """Take the next points; flagged points closer than ``merge_gap`` join one interval."""
        for i in np.flatnonzero(self.flags(t, p_res)):
            time, value = float(t[i]), float(p_res[i])
            if self.open is not None and time - self.open[1] <= self.merge_gap:
                self.open[1] = time
                self.open[4] += 1
                if abs(value) > abs(self.open[3]):
                    self.open[2], self.open[3] = time, value
            else:
                self._close()
                self.open = [time, time, time, value, 1]

    def finish(self) -> list[SpikeInterval]:
        """The flagged intervals, in time order."""
        self._close()
        return self.intervals

    def _close(self) -> None:
        if self.open is not None:
            self.intervals.append(SpikeInterval(*self.open))
            self.open = None


def flag_spikes(t: np.ndarray, p_res: np.ndarray, window: float, threshold: float) -> np.ndarray:
    """Boolean mask of the flagged points of one bond's δP series ``p_res`` [W] at times ``t`` [s]."""
    return SpikeMonitor(window, threshold, 0.0).flags(t, p_res)


def spike_intervals(t: np.ndarray, p_res: np.ndarray, window: float, threshold: float,
                    merge_gap: float) -> list[SpikeInterval]:
    """The flagged intervals of one bond, in time order."""
    monitor = SpikeMonitor(window, threshold, merge_gap)
    monitor.add(t, p_res)
    return monitor.finish()


def residual_power_spikes(record, settings) -> dict[str, list[SpikeInterval]]:
    """Flagged intervals of every bond of a run (``settings``: the scene's ``SpikeSettings``), its residual
    power read in blocks."""
    step = record.plan.base_step_ns * 1e-9
    result = {}
    for b, bond in enumerate(record.plan.bonds):
        monitor = SpikeMonitor(settings.window, settings.threshold, settings.merge_gap)
        for first, p_res in row_blocks(record.residual_power[:, b]):
            rows = first + np.flatnonzero(np.isfinite(p_res))
            rows = rows[rows > 0]  # t0 carries no residual
            monitor.add(record.row_ticks(first, first + len(p_res))[rows - first] * step, p_res[rows - first])
        result[bond.name] = monitor.finish()
    return result
