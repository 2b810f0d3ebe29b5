"""A planar pendulum: a point mass on a rigid massless rod pinned to the ground (paper 002 §4.3).

Formulation: the rod angle θ is the only coordinate, so the rod length is kept exactly at every
step (the paper integrates Cartesian coordinates with an augmented Lagrangian and symplectic Euler;
both describe the same constrained motion, the discretisations differ slightly). θ is measured from
the negative y axis, counter-clockwise; the tip is ``r = A + l (sin θ, −cos θ)``. Equation of motion::

    m l² θ̈ = −m g l sin θ + (∂r/∂θ) · F_tip,      ∂r/∂θ = l (cos θ, sin θ)

with ``F_tip`` the sum of the input forces applied to the tip and the forces of the coupling
elements that act between the tip and a terminal (paper 002 Fig. 16: the force side holds the
spring–damper, see ``subsystems.effects.planar``). Gravity acts along −y. The tip is the model's only
point; its signals have two components (x, y).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from zencosim.subsystems.effects import PlacedEffect
from zencosim.subsystems.effects.planar import planar_force
from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import Attachments, Port
from zencosim.subsystems.sketch import Sketch


@dataclass(frozen=True)
class PendulumSpec:
    """The ``[subsystems.<name>]`` parameters of a pendulum."""

    mass: float = field(metadata=quantity("kg", kind="mass"))  # m [kg]
    length: float = field(metadata=quantity("m", kind="length"))  # l [m]
    pivot: tuple[float, ...] = field(metadata=quantity("m", kind="position"))  # (x, y) of the pin A [m]
    angle0: float = field(default=0.0, metadata=quantity("rad", kind="angle"))  # θ(0) from −y, counter-clockwise [rad]
    angular_velocity0: float = field(default=0.0, metadata=quantity("rad/s", kind="angular velocity"))  # θ̇(0) [rad/s]
    gravity: float = field(default=9.81, metadata=quantity("m/s^2", kind="gravity"))  # g along −y [m/s²]

    points = ("tip",)

    def problems(self) -> list[tuple[str, str]]:
        return [] if len(self.pivot) == 2 else [("pivot", f"expected [x, y], got {list(self.pivot)}")]


class PendulumModel:
    """A pendulum subsystem: dynamics, outputs and energy (kinetic, gravity, coupling springs)."""

    name = "pendulum"
    second_order = True  # z = [θ, θ̇]
    point_dimension = 2
    coupling_roles = frozenset({"force", "motion"})
    provides_force = False
    starts_at_rest = False

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> PendulumSpec | None:
        return read_table(PendulumSpec, table, key, problems)

    def __init__(self, spec: PendulumSpec, attachments: Attachments = Attachments()) -> None:
        self.spec = spec
        self.n_dof = 1
        self.pivot = np.array(spec.pivot, dtype=np.float64)
        terminals = attachments.terminals
        inputs = [Port(p, "position") for t in terminals for p in t.position_inputs]
        inputs += [Port(p, "velocity") for t in terminals for p in t.velocity_inputs]
        inputs += [Port(p, "force") for f in attachments.force_inputs for p in f.ports]
        self.inputs: tuple[Port, ...] = tuple(inputs)
        index = {p.name: j for j, p in enumerate(self.inputs)}
        terminal_signals = {t.name: ([index[p] for p in t.position_inputs], [index[p] for p in t.velocity_inputs])
                            for t in terminals}
        placed = [PlacedEffect(*t) for t in attachments.effects]
        placed = [e for e in placed if e.effect.active()]
        self.effects: tuple[str, ...] = tuple(e.name for e in placed)
        self._elements = tuple((e.name, e.effect, terminal_signals[e.endpoints[1]]) for e in placed)
        self._force_inputs = tuple(([index[p] for p in f.ports], f.sign) for f in attachments.force_inputs)

        outputs = []
        for m in attachments.motion_outputs:
            outputs += [Port(p, "position") for p in m.position_ports] + [Port(p, "velocity") for p in m.velocity_ports]
        self._force_outputs = []
        for out in attachments.force_outputs:
            self._force_outputs.append(tuple(k for k, (name, _, _) in enumerate(self._elements) if name in out.effects))
            outputs += [Port(p, "force", feedthrough=True) for p in out.ports]
        self._motion_outputs = len(attachments.motion_outputs)
        self.outputs: tuple[Port, ...] = tuple(outputs) + (Port("energy", "energy"),)

    def initial_state(self) -> np.ndarray:
        return np.array([self.spec.angle0, self.spec.angular_velocity0], dtype=np.float64)

    def tip(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s] and ``∂r/∂θ`` [m] of the tip."""
        theta, omega = float(z[0]), float(z[1])
        s, c = math.sin(theta), math.cos(theta)
        l = self.spec.length
        jacobian = np.array([l * c, l * s])
        return self.pivot + np.array([l * s, -l * c]), omega * jacobian, jacobian

    def sketch(self, z: np.ndarray, w: np.ndarray) -> Sketch:
        """The rod from the pivot to the tip, the mass a box at the tip; the tip is the coupling point."""
        position = self.tip(z)[0]
        sketch = Sketch()
        sketch.path("rod", self.pivot, position)
        size = 0.05 * self.spec.length
        sketch.box("mass", position, (size, size))
        sketch.anchor("tip", position)
        return sketch

    def _element_forces(self, r: np.ndarray, v: np.ndarray, w: np.ndarray) -> list[tuple[np.ndarray, float]]:
        return [planar_force(effect, r, v, w[positions], w[velocities])
                for _, effect, (positions, velocities) in self._elements]

    def acceleration(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``θ̈`` [rad/s²] at time t [s] with input values ``w``."""
        r, v, jacobian = self.tip(z)
        f = np.zeros(2)
        for columns, sign in self._force_inputs:
            f += sign * w[columns]
        for force, _ in self._element_forces(r, v, w):
            f += force
        spec = self.spec
        moment = -spec.mass * spec.gravity * spec.length * math.sin(float(z[0])) + float(jacobian.dot(f))
        return np.array([moment / (spec.mass * spec.length ** 2)])

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Tip position and velocity, coupling forces (those the coupling elements exert on the remote point:
        the reaction of their force on the tip), then the energy [J] (gravity zero at y = 0)."""
        r, v, _ = self.tip(z)
        elements = self._element_forces(r, v, w)
        values = [*r, *v] * self._motion_outputs
        for members in self._force_outputs:
            values += list(-sum((elements[k][0] for k in members), np.zeros(2)))
        spec = self.spec
        energy = 0.5 * spec.mass * (spec.length * float(z[1])) ** 2 + spec.mass * spec.gravity * float(r[1])
        energy += sum(potential for _, potential in elements)
        return np.array(values + [energy])
