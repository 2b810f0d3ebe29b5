"""A user's nonlinear Python model for the identification tests (docs/models.md): a pendulum whose bob is the
motion side of a force–displacement coupling (horizontal position and velocity out, horizontal force in)::

    m L² θ'' = −m g L sin θ − c L² θ' + f_in L cos θ,    x = L sin θ,    v = L cos θ θ'

Linearised about θ = 0 on ``x = L θ`` it is a mass ``m`` on a spring ``m g / L`` with a damper ``c``.
"""
from __future__ import annotations

import numpy as np


class Pendulum:
    inputs = {"f_in": "N"}
    outputs = {"x": "m", "v": "m/s", "E": "J"}
    feedthrough = {}
    parameters = {"m": 1.0, "L": 1.0, "g": 9.81, "c": 0.0, "theta0": 0.0, "omega0": 0.0}
    second_order = True

    def __init__(self, m: float, L: float, g: float, c: float, theta0: float, omega0: float) -> None:
        self.m, self.L, self.g, self.c, self.theta0, self.omega0 = m, L, g, c, theta0, omega0

    def initial_state(self) -> np.ndarray:
        return np.array([self.theta0, self.omega0])

    def acceleration(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        theta, omega = z
        return np.array([-self.g / self.L * np.sin(theta) - self.c / self.m * omega
                         + u[0] * np.cos(theta) / (self.m * self.L)])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        theta, omega = z
        energy = 0.5 * self.m * (self.L * omega) ** 2 + self.m * self.g * self.L * (1.0 - np.cos(theta))
        return np.array([self.L * np.sin(theta), self.L * np.cos(theta) * omega, energy])


class Overflowing:
    """A model no probe can identify: any force sends it to infinity."""

    inputs = {"f_in": "N"}
    outputs = {"x": "m", "v": "m/s"}
    feedthrough = {}
    parameters = {"m": 1.0}
    second_order = True

    def __init__(self, m: float) -> None:
        self.m = m

    def initial_state(self) -> np.ndarray:
        return np.zeros(2)

    def acceleration(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array([np.inf * u[0] / self.m])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return z.copy()
