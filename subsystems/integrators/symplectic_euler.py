"""Kick–drift symplectic Euler (paper 000 §5.1, paper 002 §3.3)."""
from __future__ import annotations

import numpy as np

from zencosim.subsystems.inputs import InputPolynomial


class SymplecticEuler:
    """Kick–drift symplectic Euler: ``v⁺ = v + h a(t, x, v, u(t))``, ``x⁺ = x + h v⁺``.

    The papers' integrator (paper 000 §5.1, paper 002 §3.3); first order, one acceleration per step.
    """

    name = "symplectic_euler"
    second_order_only = True
    input_nodes = (0.0,)

    @staticmethod
    def linear_step(A_a: np.ndarray, B_a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Γ)`` of one kick–drift step: ``v⁺`` rows ``[0 I] + h A_a``, ``x⁺`` rows ``[I 0] + h v⁺``."""
        n = A_a.shape[0]
        kick = np.hstack((np.zeros((n, n)), np.eye(n))) + h * A_a
        drift = np.hstack((np.eye(n), np.zeros((n, n)))) + h * kick
        return np.vstack((drift, kick)), np.vstack((h * h * B_a, h * B_a))[None]

    def __init__(self, model, z: np.ndarray) -> None:
        n = model.n_dof
        self.model = model
        self.z = z
        self.x = z[:n]
        self.v = z[n:]

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        v = self.v
        v += h * self.model.acceleration(t, self.z, inputs.at(tau))
        self.x += h * v
