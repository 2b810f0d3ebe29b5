"""The residual-power spike detector on synthetic series: what it flags and what it leaves alone."""
from __future__ import annotations

import bisect
import math
import statistics

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.results.monitor import SpikeMonitor, flag_spikes, spike_intervals

T = np.arange(1, 10_001) * 1e-3  # 10 s of 1 ms points


def _oscillating(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 5.0 * np.sin(2 * np.pi * 3.0 * T) * (1.0 + 0.2 * rng.standard_normal(T.size))


def test_regular_residual_power_is_not_flagged():
    assert not flag_spikes(T, _oscillating(1), window=2.0, threshold=50.0).any()


def test_a_burst_is_flagged_as_one_interval_from_onset_to_end():
    p = _oscillating(2)
    burst = (T >= 4.0) & (T < 5.0)
    p[burst] *= 1e4  # a sustained burst: it must not become its own baseline
    (interval,) = spike_intervals(T, p, window=2.0, threshold=50.0, merge_gap=0.1)
    assert 4.0 <= interval.start < 4.1 and 4.9 < interval.end < 5.0
    assert abs(interval.peak) == np.max(np.abs(p))


def test_nothing_is_flagged_before_a_full_window_of_history():
    p = _oscillating(3)
    p[T < 1.0] *= 1e-6  # a run that starts at rest
    p[500] = 1e6
    assert not flag_spikes(T, p, window=2.0, threshold=50.0)[T < 2.0].any()


def _flags_by_definition(t: np.ndarray, p: np.ndarray, window: float, threshold: float) -> list[bool]:
    """The module text's rule, written out point by point: the median of |δP| over the unflagged points of the
    preceding window, once a full window of history exists."""
    kept: list[tuple[float, float]] = []  # (time, |δP|) of the points not flagged
    flagged = []
    for time, magnitude in zip(t.tolist(), np.abs(p).tolist()):
        recent = [m for s, m in kept[bisect.bisect_left(kept, (time - window, -math.inf)):]]
        flag = time - t[0] >= window and bool(recent) and magnitude > threshold * statistics.median(recent)
        flagged.append(flag)
        if not flag:
            kept.append((time, magnitude))
    return flagged


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=300), st.sampled_from([0.01, 0.05, 0.2]),
       st.sampled_from([1.5, 3.0, 50.0]))
def test_the_detector_flags_what_its_rule_flags(values, window, threshold):
    """The running median (a sorted list, points leaving it as the window passes) against the rule evaluated
    afresh at every point, on generated series with spikes and exact zeros."""
    t = np.arange(1, len(values) + 1) * 1e-3
    p = np.array(values)
    assert flag_spikes(t, p, window, threshold).tolist() == _flags_by_definition(t, p, window, threshold)


@settings(max_examples=40, deadline=None)
@given(st.integers(200, 3000), st.integers(0, 2**32 - 1), st.sampled_from([0.01, 0.2, 0.5]),
       st.sampled_from([3.0, 50.0]), st.lists(st.integers(1, 2000), min_size=1, max_size=6), st.booleans())
def test_the_detector_fed_in_blocks_flags_what_its_rule_flags(n, seed, window, threshold, blocks, irregular):
    """Long series fed in blocks of generated sizes (as a run's residual power is read), with isolated spikes,
    bursts and exact zeros, on a regular grid (decided with numpy between flags) or at irregular times (one by
    one): the flags of the rule evaluated afresh at every point."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(0.2e-3, 3e-3, n) if irregular else np.full(n, 1e-3)
    t = np.cumsum(steps)
    p = np.sin(2 * np.pi * 3.0 * t) * (1.0 + 0.2 * rng.standard_normal(n))
    p[rng.integers(0, n, 5)] *= 10.0 ** rng.integers(1, 6, 5)  # isolated spikes
    burst = rng.integers(0, n)
    p[burst:burst + rng.integers(1, 300)] *= 1e4
    p[rng.integers(0, n, 20)] = 0.0
    monitor, flags, at = SpikeMonitor(window, threshold, 0.0), [], 0
    while at < n:
        size = blocks[len(flags) % len(blocks)]
        flags.append(monitor.flags(t[at:at + size], p[at:at + size]))
        at += size
    assert np.concatenate(flags).tolist() == _flags_by_definition(t, p, window, threshold)


def _windows(n: int, sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Windows ending at n - len(sizes) … n - 1 with the given sizes, made non-decreasing at both ends."""
    end = np.arange(n - len(sizes), n)
    first = np.maximum.accumulate(np.maximum(end - sizes, 0))
    return first, end


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["uniform", "zeros", "sorted", "bursts"]),
       st.sampled_from([130, 600, 2000]), st.booleans(), st.sampled_from([None, 0.9]))
def test_median_floors_are_not_above_the_lower_middle(seed, kind, size, irregular, rank):
    """The bound that lets most points skip their window's median: never above the lower middle, the
    ((n - 1) // 2)-th smallest of the window's n values, on values with runs of zeros, sorted stretches and bursts,
    windows of one size or of drifting sizes, and with a block quantile (0.9) too high to be a bound by itself (the
    count of points below it must then give 0)."""
    from zencosim.manager.results import monitor
    rng = np.random.default_rng(seed)
    n = 3 * size
    values = {"uniform": rng.uniform(0, 1, n), "zeros": rng.uniform(0, 1, n) * (rng.uniform(0, 1, n) < 0.45),
              "sorted": np.sort(rng.exponential(1, n)), "bursts": rng.exponential(1, n) * 10.0 ** (
                  6 * (rng.uniform(0, 1, n) < 0.1))}[kind]
    sizes = rng.integers(size, int(1.5 * size), 2 * size) if irregular else np.full(2 * size, size)
    first, end = _windows(n, sizes)
    saved = monitor.FLOOR_RANK
    monitor.FLOOR_RANK = rank or saved
    try:
        floors = monitor.median_floors(values, first, end)
    finally:
        monitor.FLOOR_RANK = saved
    lower = np.array([np.partition(values[a:b], (b - a - 1) // 2)[(b - a - 1) // 2] for a, b in zip(first, end)])
    assert (floors <= lower).all()


def test_median_floors_bound_most_windows_of_a_steady_series():
    """The floors are a bound worth having: on a noisy oscillation's |δP| over 2 s windows of 1 ms points, nonzero
    everywhere and within a factor 50 of the median (so a point far below the threshold needs no median)."""
    from zencosim.manager.results import monitor
    magnitudes = np.abs(_oscillating(4))
    first, end = _windows(len(magnitudes), np.full(len(magnitudes) - 2000, 2000))
    floors = monitor.median_floors(magnitudes, first, end)
    medians = np.array([np.median(magnitudes[a:b]) for a, b in zip(first[::97], end[::97])])
    assert (floors > 0).all() and (floors[::97] > medians / 50).all()
