"""Lagrange extrapolation of exchanged signals (paper 002 Fig. 5; paper 003 Eq. 9).

The manager turns the last ``p + 1`` samples of a signal into the polynomial the receiving subsystem
evaluates over its next communication step: ZOH (p = 0), FOH (p = 1), SOH (p = 2). Polynomials are
sent as coefficients in ``tau = t - t_k`` [s], the time since the start of the receiver's step.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from zencosim.compensation.lagrange_polynomials import basis_coefficients


def lagrange_matrix(sample_times: tuple[float, ...]) -> np.ndarray:
    """``P`` such that ``P @ samples`` are the monomial coefficients of the interpolating polynomial.

    ``sample_times`` [s] are relative to the start of the receiver's step (zero or negative); the
    polynomial of degree ``len(sample_times) - 1`` passes through every sample, so it reproduces any
    polynomial of that degree exactly. It is the transposed Lagrange basis of paper 003 Eq. 9.
    """
    if len(set(sample_times)) != len(sample_times):
        raise ValueError(f"sample times must be distinct, got {sample_times}")
    return basis_coefficients(np.asarray(sample_times, dtype=np.float64)).T


@lru_cache(maxsize=1024)
def sample_matrix(offsets_ns: tuple[int, ...]) -> np.ndarray:
    """``lagrange_matrix`` of samples ``offsets_ns`` [ns] from the start of the receiver's step (zero or negative,
    oldest first): the samples of a run whose steps vary (``manager.scheme.energy_step``), which repeats a few
    spacings; ``extrapolation_matrix``'s evenly spaced samples too. Cached."""
    return lagrange_matrix(tuple(offset * 1e-9 for offset in offsets_ns))


@lru_cache(maxsize=256)
def extrapolation_matrix(points: int, sample_step_ns: int, offset_ns: int) -> np.ndarray:
    """``lagrange_matrix`` for ``points`` samples spaced ``sample_step_ns`` apart, the newest ``offset_ns``
    before the start of the receiver's step (zero in single-rate schemes; ``-sample_step_ns`` for the
    corrector of the implicit scheme, whose newest sample lies at the end of the step, paper 003
    Eq. 11). Cached: the run loop asks for the same few matrices at every step."""
    return sample_matrix(tuple(-offset_ns - (points - 1 - k) * sample_step_ns for k in range(points)))


def lagrange_coefficients(samples: np.ndarray, columns: slice | np.ndarray, newest: int, order: int,
                          sample_step_ns: int, offset_ns: int = 0, first: int = 0) -> np.ndarray:
    """Monomial coefficients (one row per power of ``tau``) of the Lagrange polynomials through the
    samples ``newest - points + 1 ... newest`` (rows of ``samples``, oldest first) of ``columns``.

    ``points = min(order, newest) + 1``: fewer points while the history is shorter, so the first step
    of a run is always a constant. ``sample_step_ns`` and ``offset_ns`` as in ``extrapolation_matrix``.
    Both schemes build every input polynomial here (Jacobi: paper 002 Fig. 5; implicit predictor and
    corrector: paper 003 Eqs. 9, 11). ``first``: the sample that ``samples[0]`` holds (a window of the newest
    samples, ``manager.scheme.window``).
    """
    points = min(order, newest) + 1
    row = newest - first
    if points == 1:
        return samples[row:row + 1, columns]
    return extrapolation_matrix(points, sample_step_ns, offset_ns).dot(samples[row - points + 1:row + 1, columns])


def evaluate(rows: list, column: int, tau: float) -> float:
    """One input of an input polynomial at ``tau`` [s] (Horner's scheme); ``rows`` are its coefficients as
    sequences of floats, one per power of ``tau``."""
    value = 0.0
    for row in reversed(rows):
        value = value * tau + row[column]
    return value
