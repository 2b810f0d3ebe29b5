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
