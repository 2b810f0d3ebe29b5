"""A user's model, written as docs/models.md describes: one mass on a line with a spring and a damper to
ground, a coupling spring–damper towards a remote point whose motion arrives as inputs, and an
applied force. The same model as the example FMUs (``zencosim.examples.fmus``)::

    m a = -k x - c v - fc + f_in,     fc = kc (x - x_in) + cc (v - v_in)

``fc`` is the force of the coupling element on the remote point (what a connection hands the other
side, unchanged); the mass feels its reaction ``-fc``.

Use it in a scene as ``model = "zencosim.examples.oscillator:Oscillator"``; a copy of this file in your
own package works the same way with your module's name.
"""
from __future__ import annotations

import numpy as np


class Oscillator:
    """A mass–spring–damper with a coupling element (SI units throughout)."""

    inputs = {"x_in": "m", "v_in": "m/s", "f_in": "N"}  # in the order of u
    outputs = {"x": "m", "v": "m/s", "a": "m/s2", "fc": "N", "inverse_mass": "1/kg", "E": "J"}  # in outputs_at()'s order
    feedthrough = {"a": ("x_in", "v_in", "f_in"), "fc": ("x_in", "v_in"), "E": ("x_in",)}  # the others: none
    parameters = {"m": 1.0, "k": 0.0, "c": 0.0, "kc": 0.0, "cc": 0.0, "x0": 0.0, "v0": 0.0}  # defaults
    second_order = True  # z = [x, v]; acceleration() gives a, and symplectic Euler applies

    def __init__(self, m: float, k: float, c: float, kc: float, cc: float, x0: float, v0: float) -> None:
        if m <= 0.0:
            raise ValueError(f"the mass m must be positive, got {m!r} kg")
        self.m, self.k, self.c, self.kc, self.cc, self.x0, self.v0 = m, k, c, kc, cc, x0, v0

    def initial_state(self) -> np.ndarray:
        return np.array([self.x0, self.v0])

    def _coupling_force(self, z: np.ndarray, u: np.ndarray) -> float:
        return self.kc * (z[0] - u[0]) + self.cc * (z[1] - u[1])

    def acceleration(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        x, v = z
        return np.array([(-self.k * x - self.c * v - self._coupling_force(z, u) + u[2]) / self.m])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        x, v = z
        a = self.acceleration(t, z, u)[0]
        stretch = x - u[0]
        energy = 0.5 * self.m * v * v + 0.5 * self.k * x * x + 0.5 * self.kc * stretch * stretch
        return np.array([x, v, a, self._coupling_force(z, u), 1.0 / self.m, energy])
