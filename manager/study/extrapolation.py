"""A study's reference where the scene gives none: the grid's own finest points extrapolated to a zero macro-step
(Richardson), with an error bar that every NRMS measured against it carries (docs/study.md, "Extrapolated
reference").

A co-simulation of fixed structure is a one-step method in its macro-step ``h`` (the micro-steps follow it:
``manager.study.grid``), so an output at a communication point has the asymptotic expansion
``y_h(t) = y(t) + c_1(t) h + c_2(t) h² + …`` (Hairer, Nørsett and Wanner, Solving ODEs I, §II.8, Theorem 8.1). The
polynomial in ``h`` through ``m`` points ``(h_i, y_i)``, evaluated at ``h = 0`` (``zero_step_weights``), cancels
every term up to ``h^(m-1)``: ``T_m``, in error ``O(h^m)``. Its error bar is ``|T_m − T_(m−1)|`` (``T_(m−1)`` from the
finest ``m − 1`` points): the estimate of ``T_(m−1)``'s error that a Richardson table gives, and in the asymptotic
range more than ``T_m``'s own. The observed order ``p`` of the three finest points solves
``‖y_2 − y_3‖ / ‖y_1 − y_2‖ = (h_3^p − h_2^p) / (h_2^p − h_1^p)`` (``observed_order``).

The points are combined at the samples they share, those of the coarsest (which must be samples of each finer
one); on the finest point's other samples the reference is that point's values plus the correction ``T_m − y_1``
interpolated by a cubic spline (the correction is the leading error term, a smooth function of ``t``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

MIN_POINTS = 3  # an extrapolation and its error bar need T_m and T_(m-1) with m - 1 >= 2


@dataclass(frozen=True)
class Samples:
    """One signal of one run: its values at its communication points."""

    times_ns: np.ndarray  # int64, the sample times [ns]
    values: np.ndarray  # the signal's values [its unit]


@dataclass(frozen=True)
class Extrapolated:
    """A reference on the finest point's samples, the steps it is extrapolated from and its error bar."""

    reference: Samples
    macro_steps: tuple[float, ...]  # [s], finest first
    order: float | None  # observed order of the three finest points (None: they do not converge)
    bar_rms: float  # RMS of T_m - T_(m-1) at the shared samples [the signal's unit]
    bar_max: float  # largest |T_m - T_(m-1)| there


def zero_step_weights(macro_steps: Sequence[float]) -> np.ndarray:
    """Weights ``w_i`` with ``Σ w_i y_i`` the value at ``h = 0`` of the polynomial through ``(h_i, y_i)``: the
    Lagrange basis at zero, ``w_i = Π_(j≠i) h_j / (h_j − h_i)``. Raises ``ValueError`` for a step given twice."""
    h = np.asarray(macro_steps, dtype=float)
    if len(set(h.tolist())) != len(h):
        raise ValueError(f"macro-steps {list(h)}: each must be given once")
    return np.array([np.prod([h[j] / (h[j] - h[i]) for j in range(len(h)) if j != i]) for i in range(len(h))])


def observed_order(macro_steps: Sequence[float], values: Sequence[np.ndarray]) -> float | None:
    """The order ``p`` with ``‖y_2 − y_3‖ / ‖y_1 − y_2‖ = (h_3^p − h_2^p) / (h_2^p − h_1^p)`` for three points, finest
    first, at shared samples (RMS norms); None where the differences do not shrink with the step as any positive
    order would have them."""
    (h1, h2, h3), (y1, y2, y3) = macro_steps, values
    fine, coarse = _rms(y1 - y2), _rms(y2 - y3)
    if not (fine > 0.0 and math.isfinite(coarse / fine)):
        return None
    target = math.log(coarse / fine)

    def excess(p: float) -> float:  # increasing in p
        return math.log((h3 ** p - h2 ** p) / (h2 ** p - h1 ** p)) - target

    low, high = 1e-6, 50.0
    if excess(low) > 0.0 or excess(high) < 0.0:
        return None
    for _ in range(200):  # bisection to the float's resolution
        middle = (low + high) / 2
        if middle in (low, high):
            break
        low, high = (middle, high) if excess(middle) < 0.0 else (low, middle)
    return (low + high) / 2


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def extrapolate(macro_steps: Sequence[float], runs: Sequence[Samples]) -> Extrapolated | str:
    """``T_m`` of the ``m >= 3`` points ``runs`` at ``macro_steps`` [s] (ascending), on the finest run's samples up to
    the coarsest's last, with its error bar (module docstring); or why there is none (a coarser run's samples that
    a finer run lacks, values that are not finite)."""
    if len(runs) < MIN_POINTS:
        return f"{len(runs)} points; the extrapolation needs {MIN_POINTS}"
    shared = runs[-1].times_ns
    at_shared = []
    for steps, run in zip(macro_steps, runs):
        index = np.minimum(np.searchsorted(run.times_ns, shared), len(run.times_ns) - 1)
        if np.any(run.times_ns[index] != shared):
            return (f"the samples of the {macro_steps[-1] * 1e3:g} ms point are not all samples of the "
                    f"{steps * 1e3:g} ms point")
        at_shared.append(np.asarray(run.values[index], dtype=float))
    if not all(np.all(np.isfinite(y)) for y in at_shared):
        return "a value that is not finite"
    extrapolated = zero_step_weights(macro_steps) @ np.array(at_shared)
    lower = zero_step_weights(macro_steps[:-1]) @ np.array(at_shared[:-1])
    finest = runs[0]
    within = finest.times_ns <= shared[-1]  # a coarser run may end earlier (manager.study.grid shortens it)
    correction = _interpolated(shared, extrapolated - at_shared[0], finest.times_ns[within])
    on_finest = Samples(finest.times_ns[within], np.asarray(finest.values, dtype=float)[within] + correction)
    return Extrapolated(on_finest, tuple(macro_steps),
                        observed_order(macro_steps[:3], at_shared[:3]), _rms(extrapolated - lower),
                        float(np.max(np.abs(extrapolated - lower))))


def _interpolated(times_ns: np.ndarray, values: np.ndarray, at_ns: np.ndarray) -> np.ndarray:
    """``values`` given at ``times_ns`` at the times ``at_ns`` (within their range): a cubic spline through them
    (straight lines between fewer than four), exact at the given times."""
    from scipy.interpolate import make_interp_spline
    t = times_ns.astype(float)
    spline = make_interp_spline(t, values, k=min(3, len(t) - 1))
    at = at_ns.astype(float)
    result = spline(at)
    given = np.searchsorted(t, at)
    exact = (given < len(t)) & (t[np.minimum(given, len(t) - 1)] == at)
    result[exact] = values[given[exact]]
    return result


def nrms_against(reference: Extrapolated, run: Samples) -> tuple[float | None, float | None]:
    """The NRMS of ``run`` against the extrapolated reference (``manager.results.summary.nrms``: RMS of the
    difference over the span of the reference, at the run's samples that the reference covers) and its error
    bar: with the reference wrong by at most ``bar_rms`` in RMS and ``bar_max`` anywhere, the NRMS against the
    exact solution lies in ``[(d − bar_rms) / (span + 2 bar_max), (d + bar_rms) / (span − 2 bar_max)]`` (``d``:
    the RMS difference; the triangle inequality, and a span that moves by at most twice the largest error); the
    bar is the larger distance of the two ends from the estimate. ``(None, None)``: a value that is not finite."""
    t_ref = reference.reference.times_ns
    covered = (run.times_ns >= t_ref[0]) & (run.times_ns <= t_ref[-1])
    values = np.asarray(run.values, dtype=float)[covered]
    if not np.all(np.isfinite(values)) or not len(values):
        return None, None
    at = _interpolated(t_ref, reference.reference.values, run.times_ns[covered])
    distance, span = _rms(values - at), float(np.max(at) - np.min(at))
    estimate = distance / span
    low = max(distance - reference.bar_rms, 0.0) / (span + 2 * reference.bar_max)
    high = (distance + reference.bar_rms) / (span - 2 * reference.bar_max) if span > 2 * reference.bar_max else math.inf
    return estimate, max(estimate - low, high - estimate)


def best_reference(methods: dict[str, list[tuple[float, Samples]]]) -> tuple[str, Extrapolated] | str:
    """Of every method's stable runs ``(macro-step [s], samples)``: the extrapolation of its finest ``m >= 3`` with the
    smallest error bar (RMS), over every method and ``m``; or why there is none."""
    found, reasons = [], []
    for method, runs in methods.items():
        runs = sorted(runs, key=lambda run: run[0])
        if len(runs) < MIN_POINTS:
            reasons.append(f"{method}: {len(runs)} stable point{'s' if len(runs) != 1 else ''}")
        for m in range(MIN_POINTS, len(runs) + 1):
            result = extrapolate([h for h, _ in runs[:m]], [samples for _, samples in runs[:m]])
            if isinstance(result, str):
                reasons.append(f"{method}: {result}")
            else:
                found.append((result.bar_rms, method, result))
    if not found:
        return (f"no method has {MIN_POINTS} stable points whose samples nest (" + "; ".join(reasons) + ")")
    _, method, result = min(found, key=lambda item: item[0])
    return method, result
