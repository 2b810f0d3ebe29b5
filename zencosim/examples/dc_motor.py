"""A DC motor drive as three subsystems joined by power bonds of two domains (docs/models.md, "Other physical
domains"): a capacitor bank feeds the motor through an electrical bond (voltage one way, current back), and the
motor's rotor drives a load through a torsional shaft, a rotational bond (torque one way, angular velocity and
angle back). Every class is a Python model as docs/models.md describes one; SI units throughout.

Supply (effort side of the electrical bond; state the capacitor voltage ``u_c``)::

    C u_c' = -i*,        u = u_c - R_s i*                       (terminal voltage: feeds the current through)

Motor (flow side of the electrical bond, effort side of the rotational one; states ``i, θ_m, ω_m``)::

    L i'     = u* - R i - k ω_m                                 (armature circuit, back-EMF k ω_m)
    J_m ω_m' = k i - τ                                          (rotor)
    τ        = k_s (θ_m - θ_l*) + c_s (ω_m - ω_l*)              (torque of the shaft on the load)

Load (flow side of the rotational bond; states ``θ_l, ω_l``)::

    J_l ω_l' = τ* - b ω_l

The monolithic system is linear (six states); ``tests/examples/test_dc_motor.py`` compares the co-simulation
with its exact solution.
"""
from __future__ import annotations

import numpy as np


class Supply:
    """A capacitor bank with an internal resistance: the voltage source of the drive."""

    inputs = {"i_in": "A"}
    outputs = {"u": "V", "E": "J"}
    feedthrough = {"u": ("i_in",)}
    parameters = {"capacitance": 10.0, "resistance": 0.05, "u0": 24.0}  # [F], [Ω], [V]

    def __init__(self, capacitance: float, resistance: float, u0: float) -> None:
        if capacitance <= 0.0 or resistance < 0.0:
            raise ValueError(f"expected a positive capacitance and a resistance >= 0, got {capacitance!r} F, "
                             f"{resistance!r} Ω")
        self.capacitance, self.resistance, self.u0 = capacitance, resistance, u0

    def initial_state(self) -> np.ndarray:
        return np.array([self.u0])

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array([-u[0] / self.capacitance])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array([z[0] - self.resistance * u[0], 0.5 * self.capacitance * z[0] * z[0]])


class Motor:
    """A permanent-magnet DC motor whose rotor drives a torsional shaft towards the load."""

    inputs = {"u_in": "V", "angle_in": "rad", "w_in": "rad/s"}
    outputs = {"i": "A", "torque": "N.m", "w": "rad/s", "E": "J"}
    feedthrough = {"torque": ("angle_in", "w_in"), "E": ("angle_in",)}
    parameters = {"resistance": 0.5, "inductance": 0.005, "motor_constant": 0.05, "rotor_inertia": 1e-4,
                  "shaft_stiffness": 50.0, "shaft_damping": 0.01}  # [Ω], [H], [N m/A], [kg m2], [N m/rad], [N m s]

    def __init__(self, resistance: float, inductance: float, motor_constant: float, rotor_inertia: float,
                 shaft_stiffness: float, shaft_damping: float) -> None:
        if inductance <= 0.0 or rotor_inertia <= 0.0:
            raise ValueError(f"expected a positive inductance and rotor inertia, got {inductance!r} H, "
                             f"{rotor_inertia!r} kg m2")
        self.R, self.L, self.k = resistance, inductance, motor_constant
        self.J, self.k_s, self.c_s = rotor_inertia, shaft_stiffness, shaft_damping

    def initial_state(self) -> np.ndarray:
        return np.zeros(3)  # i, θ_m, ω_m

    def _torque(self, z: np.ndarray, u: np.ndarray) -> float:
        return self.k_s * (z[1] - u[1]) + self.c_s * (z[2] - u[2])

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        i, _, w = z
        return np.array([(u[0] - self.R * i - self.k * w) / self.L, w, (self.k * i - self._torque(z, u)) / self.J])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        i, angle, w = z
        twist = angle - u[1]
        energy = 0.5 * self.L * i * i + 0.5 * self.J * w * w + 0.5 * self.k_s * twist * twist
        return np.array([i, self._torque(z, u), w, energy])


class Load:
    """A rotating inertia with viscous friction, driven by the torque it receives."""

    inputs = {"torque_in": "N.m"}
    outputs = {"angle": "rad", "w": "rad/s", "E": "J"}
    feedthrough = {}
    parameters = {"inertia": 1e-3, "friction": 1e-4}  # [kg m2], [N m s]

    def __init__(self, inertia: float, friction: float) -> None:
        if inertia <= 0.0:
            raise ValueError(f"expected a positive inertia, got {inertia!r} kg m2")
        self.J, self.b = inertia, friction

    def initial_state(self) -> np.ndarray:
        return np.zeros(2)  # θ_l, ω_l

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array([z[1], (u[0] - self.b * z[1]) / self.J])

    def outputs_at(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array([z[0], z[1], 0.5 * self.J * z[1] * z[1]])
