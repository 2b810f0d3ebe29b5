"""A hydraulic cylinder driven by a proportional valve (paper 002 §4.4, Eqs. 25–33, Table 5).

The state is the chamber pressures ``z = [p1, p2]``; the inputs are the actuator length ``s*`` and rate
``ṡ*`` of the mechanical side (its ``rod`` point is coupled to the arm's actuator without a coupling
element: the force is the cylinder's own, paper 002 Fig. 19)::

    f   = a_p (p2 − p1) − c ṡ                                              (Eq. 25)
    ṗ1 = β1/(a_p l4) [ a_p ṡ + a_i c_d √(2(p_P − p1)/ρ) δ_P1 − a_o c_d √(2(p1 − p_T)/ρ) δ_T1 ]   (Eq. 26)
    ṗ2 = β2/(a_p l5) [−a_p ṡ + a_o c_d √(2(p_P − p2)/ρ) δ_P2 − a_i c_d √(2(p2 − p_T)/ρ) δ_T2 ]   (Eq. 27)
    βi = (1 + a pi + b pi²)/(a + 2 b pi)                                   (Eq. 28)
    l4 = l3/2 + s0 − s,  l5 = l3/2 + s − s0                                (Eqs. 29–30)
    a_i = A_v γ,  a_o = A_v (1 − γ),  A_v = 5·10⁻⁴ m²                      (Eqs. 31–32)

(a flow whose pressure difference is negative is zero: the δ of the paper). f extends the actuator;
with the sign convention of ``subsystems.ports`` the model outputs the force on the arm's actuator
point, ``fc = f``, which the arm applies as it receives it. It has direct feedthrough through ``c ṡ*``.

Spool law (Eq. 33): ``γ = γ0 (1 − A(t) sin(2π ω t))`` with ``A`` rising linearly to ``amplitude`` over
``[0, ramp_end]``, held until ``hold_end``, falling linearly to 0 at ``stop``. Reading taken: the
paper writes ``ω = 2 rad/s`` inside ``sin(2πωt)``; the formula is followed, so the spool oscillates
at ``frequency = 2 Hz``.

Start in static equilibrium: the model receives the arm's actuator length s0 and the coupling force
that holds the arm at rest (``RestState``), and solves ṗ1 = ṗ2 = 0 at ṡ = 0 with ``a_p (p2 − p1) = f0``:
with ``r = γ0²/(1 − γ0)²``, ``p1 = (r p_P + p_T)/(1 + r)``, ``p2 = (p_P + r p_T)/(1 + r)`` and
``(1 − r)/(1 + r) = f0 / (a_p (p_P − p_T))``. The paper's γ0 ≈ 0.45435 is the result, not an input.

The circuit's stored energy is not modelled: the energy output is 0, so a run's energy is the arm's.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import Attachments, Port


@dataclass(frozen=True)
class SpoolLaw:
    """Eq. 33: ``γ = γ0 (1 − A(t) sin(2π f t))``, A a trapezoid in time."""

    amplitude: float = field(default=0.1, metadata=quantity("", minimum=0.0, maximum=1.0))  # A during the hold
    frequency: float = field(default=2.0, metadata=quantity("Hz", kind="frequency"))  # the ω of Eq. 33 [Hz]
    ramp_end: float = field(default=1.0, metadata=quantity("s", kind="time"))  # A reaches amplitude [s]
    hold_end: float = field(default=8.0, metadata=quantity("s", kind="time"))  # A starts to fall [s]
    stop: float = field(default=9.0, metadata=quantity("s", kind="time"))  # A is 0 from here on [s]

    def problems(self) -> list[tuple[str, str]]:
        if not self.ramp_end <= self.hold_end <= self.stop:
            return [("hold_end", f"expected ramp_end <= hold_end <= stop, got {self.ramp_end}, {self.hold_end}, {self.stop}")]
        return []

    def envelope(self, t: float) -> float:
        """A(t)."""
        rising = t / self.ramp_end if self.ramp_end > 0.0 else 1.0
        falling = (self.stop - t) / (self.stop - self.hold_end) if self.stop > self.hold_end else float(t < self.stop)
        return self.amplitude * max(0.0, min(rising, 1.0, falling))

    def opening(self, t: float, neutral: float) -> float:
        """γ(t) for the neutral opening γ0."""
        return neutral * (1.0 - self.envelope(t) * math.sin(2.0 * math.pi * self.frequency * t))


@dataclass(frozen=True)
class HydraulicCylinderSpec:
    """The ``[subsystems.<name>]`` parameters of the cylinder and valve (paper 002 Table 5, Eqs. 31–33)."""

    piston_area: float = field(metadata=quantity("m^2", kind="area"))  # a_p [m²]
    cylinder_length: float = field(metadata=quantity("m", kind="length"))  # l3 [m]
    friction: float = field(metadata=quantity("N s/m", kind="damping"))  # c [N s/m]
    compressibility_a: float = field(metadata=quantity("1/Pa", kind="compressibility"))  # a of Eq. 28 [1/Pa]
    compressibility_b: float = field(metadata=quantity("1/Pa^2", kind="compressibility slope"))  # b of Eq. 28 [1/Pa²]
    discharge_coefficient: float = field(metadata=quantity("", kind="discharge coefficient"))  # c_d
    density: float = field(metadata=quantity("kg/m^3", kind="density"))  # ρ [kg/m³]
    pump_pressure: float = field(metadata=quantity("Pa", kind="pressure"))  # p_P [Pa]
    tank_pressure: float = field(metadata=quantity("Pa", kind="pressure"))  # p_T [Pa]
    valve_area: float = field(default=5e-4, metadata=quantity("m^2", kind="area"))  # A_v [m²]
    spool: SpoolLaw = SpoolLaw()

    points = ("rod",)

    def problems(self) -> list[tuple[str, str]]:
        if self.pump_pressure <= self.tank_pressure:
            return [("pump_pressure", f"expected more than tank_pressure = {self.tank_pressure} Pa, got {self.pump_pressure}")]
        return []


class HydraulicCylinderModel:
    """The cylinder as a co-simulation subsystem: the force side of the actuator coupling (paper 002 Eq. 34)."""

    name = "hydraulic_cylinder"
    second_order = False  # z = [p1, p2]
    point_dimension = 1
    coupling_roles = frozenset({"force"})
    provides_force = True
    starts_at_rest = True

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> HydraulicCylinderSpec | None:
        spec = read_table(HydraulicCylinderSpec, table, key, problems, skip=("spool",))
        spool = read_table(SpoolLaw, table.get("spool", {}), f"{key}.spool", problems)
        if spec is None or spool is None:
            return None
        return dataclasses.replace(spec, spool=spool)

    def __init__(self, spec: HydraulicCylinderSpec, attachments: Attachments = Attachments()) -> None:
        if len(attachments.terminals) != 1 or len(attachments.force_outputs) != 1 or len(attachments.rest_states) != 1:
            raise ValueError(f"the {self.name} model is the force side of one coupling, with the mechanical side's "
                             "state at rest")
        self.spec = spec
        terminal = attachments.terminals[0]
        self.inputs: tuple[Port, ...] = (Port(terminal.position_inputs[0], "position"),
                                         Port(terminal.velocity_inputs[0], "velocity"))
        self.outputs: tuple[Port, ...] = (Port(attachments.force_outputs[0].ports[0], "force", feedthrough=True),
                                          Port("energy", "energy"))
        self.effects: tuple[str, ...] = ()
        rest = attachments.rest_states[0]
        self.initial_length = rest.position[0]  # s0 [m]
        self.initial_force = rest.force[0]  # f0 [N], extending the actuator
        self.neutral_opening, self._p0 = self.equilibrium(self.initial_force)
        self._flow_gain = spec.discharge_coefficient * spec.valve_area * math.sqrt(2.0 / spec.density)

    def equilibrium(self, force: float) -> tuple[float, np.ndarray]:
        """γ0 and [p1, p2] [Pa] holding the actuator force ``force`` [N] at rest (closed form, see module)."""
        spec = self.spec
        span = spec.pump_pressure - spec.tank_pressure
        phi = force / (spec.piston_area * span)
        if not -1.0 < phi < 1.0:
            raise ValueError(f"the {self.name} model cannot hold {force:.6g} N at rest: the pump holds at most "
                             f"a_p (p_P - p_T) = {spec.piston_area * span:.6g} N")
        r = (1.0 - phi) / (1.0 + phi)
        p1 = (r * spec.pump_pressure + spec.tank_pressure) / (1.0 + r)
        p2 = (spec.pump_pressure + r * spec.tank_pressure) / (1.0 + r)
        return math.sqrt(r) / (1.0 + math.sqrt(r)), np.array([p1, p2])

    def initial_state(self) -> np.ndarray:
        return self._p0.copy()

    def bulk_modulus(self, p: float) -> float:
        """β(p) [Pa], Eq. 28."""
        a, b = self.spec.compressibility_a, self.spec.compressibility_b
        return (1.0 + a * p + b * p * p) / (a + 2.0 * b * p)

    def _flow(self, area_fraction: float, pressure_drop: float) -> float:
        """Valve flow [m³/s] through ``area_fraction`` of the valve area; none against the pressure drop."""
        return area_fraction * self._flow_gain * math.sqrt(pressure_drop) if pressure_drop > 0.0 else 0.0

    def derivative(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """[ṗ1, ṗ2] [Pa/s] (Eqs. 26–32)."""
        spec = self.spec
        p1, p2 = float(z[0]), float(z[1])
        s, rate = float(w[0]), float(w[1])
        half = 0.5 * spec.cylinder_length
        l4, l5 = half + self.initial_length - s, half + s - self.initial_length
        gamma = spec.spool.opening(t, self.neutral_opening)
        pump, tank, a_p = spec.pump_pressure, spec.tank_pressure, spec.piston_area
        q1 = a_p * rate + self._flow(gamma, pump - p1) - self._flow(1.0 - gamma, p1 - tank)
        q2 = -a_p * rate + self._flow(1.0 - gamma, pump - p2) - self._flow(gamma, p2 - tank)
        return np.array([self.bulk_modulus(p1) * q1 / (a_p * l4), self.bulk_modulus(p2) * q2 / (a_p * l5)])

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``fc = f`` (Eq. 25, sign convention above), then the energy (not modelled: 0 J)."""
        f = self.spec.piston_area * (float(z[1]) - float(z[0])) - self.spec.friction * float(w[1])
        return np.array([f, 0.0])
