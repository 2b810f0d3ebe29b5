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
from scipy import ndimage

from zencosim.manager.scheme.window import row_blocks

HORIZON = 8192  # points decided with numpy at a time
AFTER_FLAG = 64  # points decided one by one after a flagged one (a burst flags many in a row)
WINDOW_SIZES = 3  # windows of at most this many sizes go through scipy's rank filters (more: one by one)
SUSPECTS = 64  # more than one point in this many above its floor: the windows' lower middles by rank filters first
FLOOR_RANK = 0.375  # the quantile of a block that bounds a window's median from below (median_floors)


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
        # the same magnitudes, sorted (a running median in O(log n) + memmove); None: sort them when next needed
        self.ordered: list[float] | None = []
        self.start: float | None = None
        self.intervals: list[SpikeInterval] = []
        self.open: list | None = None  # the interval being grown: [start, end, peak time, peak, points]

    def flags(self, t: np.ndarray, p_res: np.ndarray) -> np.ndarray:
        """Boolean mask of the flagged points among the next points ``t`` [s], ``p_res`` [W].

        Stretches without a flagged point are decided with numpy (:meth:`_stretch`): there every point's window is
        the points before it within ``window``, and only the points above a lower bound of its median need the
        median itself. A flagged point leaves the windows of the points after it, so after one the next
        ``AFTER_FLAG`` points go one by one (:meth:`_one_by_one`: the running median kept in a sorted list), and so
        do series whose times are not in order or whose values are not finite, and stretches with many points above
        their bound whose windows hold more than ``WINDOW_SIZES`` numbers of points (irregular times)."""
        t = np.asarray(t, dtype=float)
        magnitudes = np.abs(np.asarray(p_res, dtype=float))
        flagged = np.zeros(len(t), dtype=bool)
        if self.start is None and len(t):
            self.start = float(t[0])
        regular = bool(np.isfinite(magnitudes).all() and (np.diff(t) >= 0).all())
        i = 0
        while i < len(t):
            if regular:
                i, regular = self._stretch(t, magnitudes, flagged, i)
            i = self._one_by_one(t, magnitudes, flagged, i, i + AFTER_FLAG if regular else len(t))
        return flagged

    def _stretch(self, t: np.ndarray, magnitudes: np.ndarray, flagged: np.ndarray, i: int) -> tuple[int, bool]:
        """Decide points ``i`` … (at most ``HORIZON``) with numpy, up to the first flagged one (flagged here);
        returns the first point not decided, and False where the windows hold too many numbers of points (nothing
        decided).

        A point can only be flagged above ``threshold`` times a lower bound of its baseline (:func:`median_floors`);
        the few points above it are judged by their window's median itself. Where many are (a baseline that changes
        fast within its window), scipy's rank filters give every window's lower middle first."""
        stop = min(len(t), i + HORIZON)
        held = len(self.times)  # the unflagged points of the window so far, then the new ones
        times = np.concatenate((np.fromiter(self.times, float, held), t[i:stop]))
        values = np.concatenate((np.fromiter(self.magnitudes, float, held), magnitudes[i:stop]))
        new = np.arange(held, len(times))
        sizes = new - np.searchsorted(times, times[new] - self.window, side="left")  # the window: the points before
        judged = (times[new] - self.start >= self.window) & (sizes > 0)  # a full window of history, not empty
        suspects = judged & (values[new] > self.threshold * median_floors(values, new - sizes, new))
        if np.count_nonzero(suspects) > len(new) // SUSPECTS:
            kinds = np.unique(sizes[judged]).tolist()
            if len(kinds) > WINDOW_SIZES:
                return i, False
            lower = np.zeros(len(new))
            for size in kinds:  # the median of each window of ``size`` points: its middle one, or the lower middle one
                at = judged & (sizes == size)
                ends = new[at] - size + size // 2  # where a centred filter of ``size`` sees the points before new[at]
                lower[at] = ndimage.rank_filter(values, (size - 1) // 2, size=size)[ends]
            suspects &= values[new] > self.threshold * lower
        decided = len(new)  # up to the first spike
        for k in np.flatnonzero(suspects).tolist():
            if values[new[k]] > self.threshold * _median(values[new[k] - sizes[k]:new[k]]):
                decided = k
                break
        end = held + decided  # the unflagged points, as the one-by-one loop leaves its window after the last
        if end:
            first = int(np.searchsorted(times[:end], times[end - 1] - self.window, side="left"))
            self.times = deque(times[first:end].tolist())
            self.magnitudes = deque(values[first:end].tolist())
            self.ordered = None
        if decided < len(new):
            flagged[i + decided] = True
            return i + decided + 1, True
        return stop, True

    def _one_by_one(self, t: np.ndarray, magnitudes: np.ndarray, flagged: np.ndarray, i: int, stop: int) -> int:
        """Decide points ``i`` … ``stop - 1`` one by one; returns where it stopped."""
        stop = min(stop, len(t))
        if self.ordered is None and i < stop:
            self.ordered = sorted(self.magnitudes)
        times, kept, ordered = self.times, self.magnitudes, self.ordered
        window, threshold, start = self.window, self.threshold, self.start
        insort, position = bisect.insort, bisect.bisect_left
        for i, (time, magnitude) in enumerate(zip(t[i:stop].tolist(), magnitudes[i:stop].tolist()), start=i):
            oldest = time - window
            while times and times[0] < oldest:
                times.popleft()
                del ordered[position(ordered, kept.popleft())]
            if time - start >= window and ordered:  # a full window of history
                middle = len(ordered) // 2
                baseline = ordered[middle] if len(ordered) % 2 else 0.5 * (ordered[middle - 1] + ordered[middle])
                if magnitude > threshold * baseline:
                    flagged[i] = True
                    continue
            times.append(time)
            kept.append(magnitude)
            insort(ordered, magnitude)
        return stop

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


def median_floors(values: np.ndarray, first: np.ndarray, end: np.ndarray) -> np.ndarray:
    """For each window ``values[first[k]:end[k]]`` (not empty; ``first`` and ``end`` not decreasing), a number not
    above its lower middle value, the ``(n - 1) // 2``-th smallest of its ``n``: the least of the
    ``FLOOR_RANK``-quantiles of the blocks of ``n // 32`` points (counted from ``values[0]``) that lie wholly in the
    windows of its group of as many windows. At most ``FLOOR_RANK`` of a block's points lie below its quantile, so at
    most that many per block, and the points of the window outside those blocks, lie below the least of them; where
    that is not fewer than the lower middle's rank, or a block would hold fewer than 4 points, the floor is 0."""
    floors, inner = np.zeros(len(end)), np.zeros(len(end), dtype=np.int64)
    sizes = end - first
    block = int(sizes.min()) // 32 if len(sizes) else 0
    if block < 4:
        return floors
    rank = int(FLOOR_RANK * block)  # at most ``rank`` points of a block lie below its ``rank``-th smallest
    count = len(values) // block
    quantiles = np.partition(values[:count * block].reshape(count, block), rank, axis=1)[:, rank].tolist()
    for group in range(0, len(end), block):  # the blocks inside the windows of all the group's points
        last = min(group + block, len(end))
        inside = quantiles[-(-int(first[last - 1]) // block):int(end[group]) // block]
        if inside:
            floors[group:last] = min(inside)
            inner[group:last] = len(inside)
    floors[inner * rank + (sizes - inner * block) > (sizes - 1) // 2] = 0.0
    return floors


def _median(window: np.ndarray) -> float:
    """The median of ``window`` as the one-by-one loop takes it: its middle value, or the mean of its middle two."""
    middle = len(window) // 2
    if len(window) % 2:
        return float(np.partition(window, middle)[middle])
    lower, upper = np.partition(window, (middle - 1, middle))[middle - 1:middle + 1].tolist()
    return 0.5 * (lower + upper)


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
