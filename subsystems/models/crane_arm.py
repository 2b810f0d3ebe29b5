"""The two-link arm of the hydraulic crane (paper 002 §4.4, Fig. 17, Table 5), the mechanical side.

Link 1 (length l1, uniform mass m1) is pinned to the ground at A; link 2 (length l2, massless) is
pinned to the end Q of link 1 and carries the point mass m3 at its end P; m2 sits at Q. The absolute
link angles θ1, θ2 (from +x, counter-clockwise) are the coordinates, so the joints hold exactly.
A hydraulic actuator joins the fixed point B to the point C of link 1 at ``actuator_attachment``
from A; the model's one point, ``actuator``, is the actuator: its position is the actuator length
``s = |C − B|`` and its velocity ``ṡ = J θ̇1`` with ``J = ∂s/∂θ1``. A force F along the actuator
(positive extending it) acts as the generalised force ``J F`` on θ1. Equations of motion (Lagrange)::

    [I_A + (m2+m3) l1²      m3 l1 l2 cos θ12] [θ̈1]   [ m3 l1 l2 sin θ12 θ̇2²]   [Q_g1 + J F]
    [m3 l1 l2 cos θ12       m3 l2²          ] [θ̈2] + [−m3 l1 l2 sin θ12 θ̇1²] = [Q_g2      ]

with ``θ12 = θ1 − θ2``, ``I_A = m1 l1²/3``, ``Q_g1 = −g l1 cos θ1 (m1/2 + m2 + m3)``, ``Q_g2 = −g m3 l2 cos θ2``.

Reading taken (the figure is missing from the text): C is the middle of link 1. With B = (√3/2, 0) m,
θ1(0) = π/6 and link 2 hanging (θ2(0) = 3π/2), the static actuator force is then 8.83 kN, and the
hydraulic equilibrium it implies gives the paper's spool position γ0 ≈ 0.45435 (attaching C at Q
would need half that force and γ0 ≈ 0.477); see tests/subsystems/test_hydraulic_crane.py.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import Attachments, Port, RestState
from zencosim.subsystems.sketch import Sketch


@dataclass(frozen=True)
class CraneArmSpec:
    """The ``[subsystems.<name>]`` parameters of the arm (paper 002 Table 5)."""

    link1_length: float = field(metadata=quantity("m", kind="length"))  # l1 [m]
    link2_length: float = field(metadata=quantity("m", kind="length"))  # l2 [m]
    link1_mass: float = field(metadata=quantity("kg", kind="mass"))  # m1 [kg], uniform along link 1
    mass_q: float = field(metadata=quantity("kg", kind="mass"))  # m2 [kg] at Q, the end of link 1
    mass_p: float = field(metadata=quantity("kg", kind="mass"))  # m3 [kg] at P, the end of link 2
    cylinder_base: tuple[float, ...] = field(metadata=quantity("m", kind="position"))  # B = (x, y) [m]; A is the origin
    actuator_attachment: float = field(metadata=quantity("m", kind="length"))  # |AC| [m]
    angle1_0: float = field(metadata=quantity("rad", kind="angle"))  # θ1(0) [rad] from +x, counter-clockwise
    angle2_0: float = field(metadata=quantity("rad", kind="angle"))  # θ2(0) [rad], absolute
    gravity: float = field(default=9.81, metadata=quantity("m/s^2", kind="gravity"))  # g along −y [m/s²]

    points = ("actuator",)

    def problems(self) -> list[tuple[str, str]]:
        found = []
        if len(self.cylinder_base) != 2:
            found.append(("cylinder_base", f"expected [x, y], got {list(self.cylinder_base)}"))
        if self.actuator_attachment > self.link1_length:
            found.append(("actuator_attachment", f"expected at most link1_length = {self.link1_length} m, "
                                                 f"got {self.actuator_attachment}"))
        return found


class CraneArmModel:
    """The arm as a co-simulation subsystem: the motion side of the actuator coupling (paper 002 Fig. 19)."""

    name = "crane_arm"
    second_order = True  # z = [θ1, θ2, θ̇1, θ̇2]
    point_dimension = 1
    coupling_roles = frozenset({"motion"})
    provides_force = False
    starts_at_rest = False

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> CraneArmSpec | None:
        return read_table(CraneArmSpec, table, key, problems)

    def __init__(self, spec: CraneArmSpec, attachments: Attachments = Attachments()) -> None:
        if attachments.terminals or attachments.force_outputs:
            raise ValueError(f"the {self.name} model can only be the motion side of a coupling")
        self.spec = spec
        self.n_dof = 2
        self.inputs: tuple[Port, ...] = tuple(Port(f.ports[0], "force") for f in attachments.force_inputs)
        self._signs = np.array([f.sign for f in attachments.force_inputs])
        outputs = []
        for m in attachments.motion_outputs:
            outputs += [Port(m.position_ports[0], "position"), Port(m.velocity_ports[0], "velocity")]
        self._motion_outputs = len(attachments.motion_outputs)
        self.outputs: tuple[Port, ...] = tuple(outputs) + (Port("energy", "energy"),)
        self.effects: tuple[str, ...] = ()
        l1, l2 = spec.link1_length, spec.link2_length
        self._M11 = spec.link1_mass * l1 ** 2 / 3.0 + (spec.mass_q + spec.mass_p) * l1 ** 2  # [kg m²]
        self._M12 = spec.mass_p * l1 * l2  # times cos θ12 [kg m²]
        self._M22 = spec.mass_p * l2 ** 2  # [kg m²]
        self._weight1 = spec.gravity * l1 * (0.5 * spec.link1_mass + spec.mass_q + spec.mass_p)  # [N m]
        self._weight2 = spec.gravity * spec.mass_p * l2  # [N m]
        self._base = np.array(spec.cylinder_base, dtype=np.float64)

    def initial_state(self) -> np.ndarray:
        return np.array([self.spec.angle1_0, self.spec.angle2_0, 0.0, 0.0])

    def actuator(self, theta1: float) -> tuple[float, float]:
        """Actuator length s [m] and ``J = ∂s/∂θ1`` [m] at link angle θ1 [rad]."""
        a = self.spec.actuator_attachment
        c, s = math.cos(theta1), math.sin(theta1)
        dx, dy = a * c - self._base[0], a * s - self._base[1]
        length = math.hypot(dx, dy)
        return length, (dx * (-a * s) + dy * (a * c)) / length

    def acceleration(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        theta1, theta2, omega1, omega2 = (float(v) for v in z)
        _, J = self.actuator(theta1)
        force = float(self._signs.dot(w))  # along the actuator, positive extending it [N]
        c12, s12 = math.cos(theta1 - theta2), math.sin(theta1 - theta2)
        m12 = self._M12 * c12
        r1 = -self._weight1 * math.cos(theta1) + J * force - self._M12 * s12 * omega2 * omega2
        r2 = -self._weight2 * math.cos(theta2) + self._M12 * s12 * omega1 * omega1
        det = self._M11 * self._M22 - m12 * m12
        return np.array([(self._M22 * r1 - m12 * r2) / det, (self._M11 * r2 - m12 * r1) / det])

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Actuator length and rate, then the mechanical energy [J] (gravity zero at y = 0)."""
        theta1, theta2, omega1, omega2 = (float(v) for v in z)
        length, J = self.actuator(theta1)
        kinetic = 0.5 * (self._M11 * omega1 ** 2 + 2.0 * self._M12 * math.cos(theta1 - theta2) * omega1 * omega2
                         + self._M22 * omega2 ** 2)
        potential = self._weight1 * math.sin(theta1) + self._weight2 * math.sin(theta2)
        return np.array([length, J * omega1] * self._motion_outputs + [kinetic + potential])

    def sketch(self, z: np.ndarray, w: np.ndarray) -> Sketch:
        """Link 1 from A to Q, link 2 from Q to P, the masses at Q and P, and the actuator (the cylinder)
        from B to C; the actuator point is C, its force along B → C."""
        theta1, theta2 = float(z[0]), float(z[1])
        l1, l2, a = self.spec.link1_length, self.spec.link2_length, self.spec.actuator_attachment
        e1, e2 = np.array([math.cos(theta1), math.sin(theta1)]), np.array([math.cos(theta2), math.sin(theta2)])
        q, c = l1 * e1, a * e1
        p = q + l2 * e2
        sketch = Sketch()
        sketch.path("link1", (0.0, 0.0), q)
        sketch.path("link2", q, p)
        sketch.path("cylinder", self._base, c)
        size = 0.05 * l1
        sketch.box("m2", q, (size, size))
        sketch.box("m3", p, (size, size))
        along = (c - self._base) / np.hypot(*(c - self._base))
        for point in self.spec.points:
            sketch.anchor(point, c, along)
        return sketch

    def rest_state(self, point: str) -> RestState:
        """The actuator length at t = 0 and the coupling force ``F`` (the force on the actuator point, which
        the arm applies as it receives it) that holds the arm at rest there; link 2 must hang at rest by itself."""
        theta1, theta2 = self.spec.angle1_0, self.spec.angle2_0
        if abs(self._weight2 * math.cos(theta2)) > 1e-9 * max(self._weight2, 1e-300):
            raise ValueError(f"the {self.name} model does not start at rest: link 2 at θ2(0) = {theta2} rad is "
                             "not hanging vertically")
        length, J = self.actuator(theta1)
        force = float(self._weight1 * math.cos(theta1) / J)  # F with J F = −Q_g1 [N]
        return RestState(point, (float(length),), (force,))
