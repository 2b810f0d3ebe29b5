"""Classical fourth-order Runge–Kutta."""
from __future__ import annotations

import numpy as np

from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.integrators.base import state_derivative


class RungeKutta4:
    """Classical fourth-order Runge–Kutta on ``ż = f(t, z, u(t))``; inputs at t, t + h/2, t + h."""

    name = "rk4"
    second_order_only = False
    input_nodes = (0.0, 0.5, 1.0)

    @staticmethod
    def linear_step(A_a: np.ndarray, B_a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Γ)`` of one RK4 step on ``z' = F z + G w``, ``F = [[0, I], A_a]``, ``G = [[0], B_a]``.

        Each stage is a matrix on ``[z, w(τ), w(τ + h/2), w(τ + h)]``.
        """
        n, n_in = A_a.shape[0], B_a.shape[1]
        F = np.vstack((np.hstack((np.zeros((n, n)), np.eye(n))), A_a))
        G = np.vstack((np.zeros((n, n_in)), B_a))
        width = 2 * n + 3 * n_in
        z = np.eye(2 * n, width)

        def derivative(state: np.ndarray, node: int) -> np.ndarray:
            k = F @ state
            k[:, 2 * n + node * n_in:2 * n + (node + 1) * n_in] += G
            return k

        k1 = derivative(z, 0)
        k2 = derivative(z + 0.5 * h * k1, 1)
        k3 = derivative(z + 0.5 * h * k2, 1)
        k4 = derivative(z + h * k3, 2)
        step = z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        Gamma = np.stack([step[:, 2 * n + i * n_in:2 * n + (i + 1) * n_in] for i in range(3)])
        return step[:, :2 * n], Gamma

    def __init__(self, model, z: np.ndarray) -> None:
        self.model = model
        self.z = z

    def _derivative(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return state_derivative(self.model, t, z, w)

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        z = self.z
        half = 0.5 * h
        w_mid = inputs.at(tau + half)
        k1 = self._derivative(t, z, inputs.at(tau))
        k2 = self._derivative(t + half, z + half * k1, w_mid)
        k3 = self._derivative(t + half, z + half * k2, w_mid)
        k4 = self._derivative(t + h, z + h * k3, inputs.at(tau + h))
        z += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
