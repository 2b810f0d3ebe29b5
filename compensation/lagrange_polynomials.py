"""Lagrange polynomials of degree k on the macro-time grid (paper 003, Eqs. 9, 11, 35, 37, 59, 61).

Time is local to the macro-step and dimensionless: ``s = (t - T_N) / H``, so ``T_{N-j}`` is ``s = -j``
and ``T_{N+1}`` is ``s = 1``. Node values are ordered newest first, as in the paper.
"""
from __future__ import annotations

import numpy as np


def predictor_nodes(k: int) -> np.ndarray:
    """Sampling points of the predictor (extrapolation) polynomial, Eq. (9): T_N, T_{N-1}, ..., T_{N-k}."""
    return -np.arange(_checked_degree(k) + 1, dtype=float)


def corrector_nodes(k: int) -> np.ndarray:
    """Sampling points of the corrector (interpolation) polynomial, Eq. (11): T_{N+1}, T_N, ..., T_{N-k+1}.

    For ``k = 0`` this is T_{N+1} alone: the corrector holds the corrected coupling variable constant
    over the whole macro-step.
    """
    return 1.0 - np.arange(_checked_degree(k) + 1, dtype=float)


def basis_coefficients(nodes: np.ndarray) -> np.ndarray:
    """Monomial coefficients of the Lagrange basis: ``ell_j(s) = sum_i P[j, i] s**i``.

    ``ell_j(nodes[a]) = delta_ja`` reads ``P V^T = I`` with the Vandermonde matrix ``V[a, i] = nodes[a]**i``.
    """
    vandermonde = np.vander(nodes, increasing=True)
    return np.linalg.inv(vandermonde).T


def basis_values(nodes: np.ndarray, s: float) -> np.ndarray:
    """``ell_j(s)`` for every node j."""
    return basis_coefficients(nodes) @ s ** np.arange(len(nodes))


def extrapolation_weights(k: int) -> np.ndarray:
    """Weights of the predicted value at T_{N+1}: ``e^p_{N+1} = sum_j w_j e_{N-j}`` (Eq. 9 at s = 1).

    ``[1]``, ``[2, -1]`` and ``[3, -3, 1]`` for k = 0, 1, 2.
    """
    return basis_values(predictor_nodes(k), 1.0)


def _checked_degree(k: int) -> int:
    if int(k) != k or k < 0:
        raise ValueError(f"the Lagrange approximation degree k must be a non-negative integer; got {k!r}")
    return int(k)
