"""What a study's table says: Pareto fronts, fitted orders, largest stable macro-steps, the cheapest setting for
an accuracy target (docs/study.md).

Pure functions of costs, errors, macro-steps and verdicts (``manager.study.study`` says which columns of the
table they are).
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np


def pareto_front(costs: Sequence[float], errors: Sequence[float]) -> list[int]:
    """Indices of the non-dominated points (lower cost and lower error are better): no other point is at most as
    costly and at most as wrong and better in one of the two. Equal points are all kept."""
    points = list(zip(costs, errors))
    return [i for i, (c, e) in enumerate(points)
            if not any(c2 <= c and e2 <= e and (c2 < c or e2 < e) for c2, e2 in points)]


def fitted_order(macro_steps: Sequence[float], errors: Sequence[float]) -> float | None:
    """Least-squares slope of ``ln error`` over ``ln macro_step``: the observed order of convergence (None with
    fewer than two distinct steps or a non-positive error)."""
    h, e = np.asarray(macro_steps, dtype=float), np.asarray(errors, dtype=float)
    if len(set(h.tolist())) < 2 or np.any(e <= 0.0) or not np.all(np.isfinite(e)):
        return None
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def largest_stable_step(macro_steps: Sequence[float], stable: Sequence[bool]) -> float | None:
    """The largest macro-step at which the method is stable together with every smaller one of the grid (None:
    unstable at the smallest)."""
    largest = None
    for h, ok in sorted(zip(macro_steps, stable)):
        if not ok:
            break
        largest = h
    return largest


def stability_bracket(macro_steps: Sequence[float], stable: Sequence[bool]) -> tuple[float, float] | None:
    """``(largest stable step, next step of the grid)`` when the method turns unstable inside the grid."""
    largest = largest_stable_step(macro_steps, stable)
    above = sorted(h for h in macro_steps if largest is not None and h > largest)
    return (largest, above[0]) if above else None


def step_for_target(macro_steps: Sequence[float], errors: Sequence[float], stable: Sequence[bool],
                    target: float) -> float | None:
    """The largest macro-step of the grid at which a stable run meets ``error <= target``."""
    meeting = [h for h, e, ok in zip(macro_steps, errors, stable) if ok and e is not None and e <= target]
    return max(meeting) if meeting else None


def cheapest(costs: Sequence[float], errors: Sequence[float], stable: Sequence[bool], target: float) -> int | None:
    """Index of the cheapest stable point with ``error <= target`` (the lower error among equal costs)."""
    meeting = [i for i, (e, ok) in enumerate(zip(errors, stable)) if ok and e is not None and e <= target]
    return min(meeting, key=lambda i: (costs[i], errors[i])) if meeting else None


TIE_RULE = ("costs whose measured ranges (fastest to slowest of the repeats) overlap that of the cheapest are tied; "
            "among tied settings the one with fewer exchanges per simulated second is chosen, then the one with "
            "the lower error, then the lower median cost")


def tied_with(ranges: Sequence[tuple[float, float]], candidates: Sequence[int], first: int) -> list[int]:
    """The candidates whose measured cost range ``(fastest, slowest)`` overlaps that of ``first`` (itself
    included): their costs differ by less than the spread of the measurements, so they are not told apart."""
    low, high = ranges[first]
    return [i for i in candidates if ranges[i][0] <= high and ranges[i][1] >= low]


def answer(costs: Sequence[float], ranges: Sequence[tuple[float, float]], errors: Sequence[float],
           stable: Sequence[bool], target: float, exchanges: Callable[[int], float]) -> tuple[int | None, list[int]]:
    """The setting to recommend for ``error <= target``, and every point tied with the cheapest (``TIE_RULE``).

    The cheapest stable point meeting the target (by median cost, ``cheapest``) is the answer unless another
    such point's cost range overlaps its range: then the costs are equal within the measured spread, and the
    tie is broken by fewer ``exchanges(i)`` (per simulated second: asked only of tied points), then the lower
    error, then the lower median cost. Returns ``(None, [])`` when no point meets the target; ``tied`` holds the
    answer alone when nothing ties with it.
    """
    first = cheapest(costs, errors, stable, target)
    if first is None:
        return None, []
    meeting = [i for i, (e, ok) in enumerate(zip(errors, stable)) if ok and e is not None and e <= target]
    tied = tied_with(ranges, meeting, first)
    if len(tied) == 1:
        return first, tied
    counted = {i: exchanges(i) for i in tied}
    tied.sort(key=lambda i: (counted[i], errors[i], costs[i], i))
    return tied[0], tied
