"""Input polynomials: how a subsystem sees its inputs between two communication points."""
from __future__ import annotations

import numpy as np


class InputPolynomial:
    """Every input port as a polynomial in ``tau = t - t_k`` [s] over one communication step.

    ``coefficients[i, j]`` multiplies ``tau**i`` for input port ``j``; the manager builds them by
    Lagrange extrapolation (order 0, 1 or 2) and the subsystem evaluates them at every micro-step.
    """

    __slots__ = ("coefficients", "order")

    def __init__(self, coefficients: np.ndarray) -> None:
        if coefficients.ndim != 2:
            raise ValueError(f"input polynomial coefficients must be 2-D (order+1, ports), got shape {coefficients.shape}")
        self.coefficients = coefficients
        self.order = coefficients.shape[0] - 1

    @classmethod
    def constant(cls, values: np.ndarray) -> "InputPolynomial":
        return cls(np.asarray(values, dtype=np.float64).reshape(1, -1))

    def at(self, tau: float) -> np.ndarray:
        """Input values at ``tau`` seconds after the start of the step (Horner's scheme)."""
        c = self.coefficients
        if self.order == 0:
            return c[0]
        w = c[self.order] * tau
        for i in range(self.order - 1, 0, -1):
            w += c[i]
            w *= tau
        w += c[0]
        return w
