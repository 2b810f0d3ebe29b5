"""Fixed-step integrators. One class per method; ``INTEGRATORS`` maps scene names to classes.

An integrator is bound to one model and one state vector ``z`` (updated in place) and advances it by
one micro-step ``h`` with the inputs evaluated where the method needs them. Second-order models
(``model.second_order``) have ``z = [x, v]`` and give the acceleration; first-order models (a
hydraulic circuit) give ``ż`` itself. Symplectic Euler needs the second-order form.
"""
from __future__ import annotations

import numpy as np

from subsystems.inputs import InputPolynomial


def state_derivative(model, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``ż`` at time t [s] with input values ``w``: ``[v, a]`` for a second-order model."""
    if model.second_order:
        return np.concatenate((z[model.n_dof:], model.acceleration(t, z, w)))
    return model.derivative(t, z, w)


class SymplecticEuler:
    """Kick–drift symplectic Euler: ``v⁺ = v + h a(t, x, v, u(t))``, ``x⁺ = x + h v⁺``.

    The papers' integrator (paper 000 §5.1, paper 002 §3.3); first order, one acceleration per step.
    """

    name = "symplectic_euler"
    second_order_only = True

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


class RungeKutta4:
    """Classical fourth-order Runge–Kutta on ``ż = f(t, z, u(t))``; inputs at t, t + h/2, t + h."""

    name = "rk4"
    second_order_only = False

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


INTEGRATORS: dict[str, type] = {cls.name: cls for cls in (SymplecticEuler, RungeKutta4)}
