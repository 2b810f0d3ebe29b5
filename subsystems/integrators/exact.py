"""Exact integration of a linear, time-invariant model with polynomial inputs.

With ``a = A_a z + B_a w`` the state ``z = [x, v]`` obeys ``z' = F z + G w`` with ``F = [[0, I], A_a]``
and ``G = [[0], B_a]``. Over one micro-step ``s ∈ [0, h]`` with the input polynomial re-expanded at
the start of the micro-step, ``w(τ + s) = Σ_i c_i s^i``,

    z(h) = e^{F h} z(0) + Σ_i Ψ_i c_i,      Ψ_i = ∫_0^h e^{F (h − s)} G s^i ds,

which one matrix exponential of the system augmented with a chain of integrators gives
(``compensation.macro_step_response``, per input). Paper 003 integrates its test model analytically
(§1, §2.1.1); with this integrator the runtime has no integration error either and reproduces the
recurrence system of the coupling method to rounding. Models provide ``linear_dynamics()``.
"""
from __future__ import annotations

from math import comb

import numpy as np

from zencosim.compensation.macro_step_response import polynomial_input_response
from zencosim.subsystems.inputs import InputPolynomial


def taylor_shift(coefficients: np.ndarray, tau: float) -> np.ndarray:
    """Coefficients in ``s`` of the polynomial ``p(tau + s)`` given those of ``p`` (rows: powers)."""
    rows = coefficients.shape[0]
    shift = np.array([[comb(j, i) * tau ** (j - i) if j >= i else 0.0 for j in range(rows)] for i in range(rows)])
    return shift @ coefficients


def polynomial_step(A_a: np.ndarray, B_a: np.ndarray, h: float, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """``e^{F h}`` and ``Ψ`` (2n, rows, inputs): the exact step for input polynomials with ``rows``
    coefficients (module docstring)."""
    n = A_a.shape[0]
    F = np.vstack((np.hstack((np.zeros((n, n)), np.eye(n))), A_a))
    G = np.vstack((np.zeros((n, B_a.shape[1])), B_a))
    powers = h ** np.arange(rows)  # the dimensionless s of macro_step_response is s / h
    responses = [polynomial_input_response(h * F, h * column, rows - 1) for column in G.T]
    if not responses:
        from scipy.linalg import expm  # here: loading scipy.linalg costs every process that never integrates exactly
        return expm(h * F), np.zeros((2 * n, rows, 0))
    return responses[0][0], np.stack([psi * powers for _, psi in responses], axis=-1)


class ExactLinear:
    """``z ← e^{F h} z + Σ_i Ψ_i c_i`` per micro-step (module docstring); exact up to rounding."""

    name = "exact"
    second_order_only = True  # z = [x, v], the acceleration from linear_dynamics()
    input_nodes = (0.0, 0.5, 1.0)  # of linear_step: enough for the input polynomials of the protocol (degree <= 2)

    @staticmethod
    def linear_step(A_a: np.ndarray, B_a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Γ)`` with ``z⁺ = Φ z + Σ_i Γ_i w(τ + θ_i h)``, exact for inputs of degree <= 2: the
        Lagrange polynomial through the three node values is the input itself."""
        Phi, Psi = polynomial_step(A_a, B_a, h, 3)
        nodes = np.array(ExactLinear.input_nodes) * h
        to_coefficients = np.linalg.inv(np.vander(nodes, increasing=True))  # c = V⁻¹ w(nodes)
        return Phi, np.einsum("nri,rk->kni", Psi, to_coefficients)

    def __init__(self, model, z: np.ndarray) -> None:
        self.A_a, self.B_a = model.linear_dynamics()
        self.z = z
        self._transitions: dict[tuple[float, int], tuple[np.ndarray, np.ndarray]] = {}

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        coefficients = inputs.coefficients if tau == 0.0 else taylor_shift(inputs.coefficients, tau)
        key = (h, coefficients.shape[0])
        if key not in self._transitions:
            self._transitions[key] = polynomial_step(self.A_a, self.B_a, h, key[1])
        Phi, Psi = self._transitions[key]
        self.z[:] = Phi @ self.z + np.einsum("nri,ri->n", Psi, coefficients)
