"""A rigid link in the plane: the links of the double pendulum of paper 003 §4 (Fig. 5).

Generalised coordinates ``q``: the centre of mass ``S = (x, y)`` and the angle ``φ`` of the link from the
x-axis (counter-clockwise) for a free link; ``φ`` alone for a link whose end A turns about a fixed
ground point (``pivot = "A"``; ``S = pivot + (l/2) e``). With ``e = (cos φ, sin φ)`` and
``n = (−sin φ, cos φ)`` the points are ``A = S − (l/2) e``, ``B = S + (l/2) e`` and ``S``.

Equations of motion (Lagrange, the pivot eliminated by the coordinates)::

    M q'' = Q(q, q') + Σ_force Gᵀ s λ* + G_Dᵀ F_D,      G_D q'' = ã* − Ġ_D q'

with ``M = diag(m, m, J)`` (free) or ``J + m l²/4`` (pivot), ``Q`` gravity ``(0, −m g)`` and the viscous
force ``−d v_S`` acting at the centre of mass, ``G = ∂P/∂q`` of a joint point ``P``. A force-driven
joint side applies ``s λ*``; a displacement-driven side makes its point follow ``ã*`` (index 1, paper
003 Eq. 33b), with ``F_D`` the force this takes (the saddle-point system is solved at every call).
A point can only follow a prescribed planar acceleration if it has two degrees of freedom: not on a
pivoted link (one).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import Attachments, Port
from zencosim.subsystems.sketch import Sketch

POINT_OFFSETS = {"A": -0.5, "B": 0.5, "S": 0.0}  # position of each point along the link, in lengths from S


@dataclass(frozen=True)
class LinkSpec:
    """One planar link: inertia, geometry, initial state, gravity and damping (zero: not built)."""

    mass: float = field(metadata=quantity("kg", kind="mass"))  # m [kg]
    inertia: float = field(metadata=quantity("kg m^2", kind="inertia"))  # J about S [kg m^2]
    length: float = field(metadata=quantity("m", kind="length"))  # l [m], A to B
    angle0: float = field(metadata=quantity("rad", kind="angle"))  # φ at t = 0 [rad], from the x-axis
    # φ' at t = 0 [rad/s]
    angular_velocity0: float = field(default=0.0, metadata=quantity("rad/s", kind="angular velocity"))
    pivot: Literal["none", "A"] = "none"  # "A": end A turns about the fixed point (pivot_x, pivot_y)
    pivot_x: float = field(default=0.0, metadata=quantity("m", kind="position"))
    pivot_y: float = field(default=0.0, metadata=quantity("m", kind="position"))
    # centre of mass at t = 0 (free link) [m]
    x0: float | None = field(default=None, metadata=quantity("m", kind="position"))
    y0: float | None = field(default=None, metadata=quantity("m", kind="position"))
    # its velocity at t = 0 (free link) [m/s]
    vx0: float | None = field(default=None, metadata=quantity("m/s", kind="velocity"))
    vy0: float | None = field(default=None, metadata=quantity("m/s", kind="velocity"))
    gravity: float = field(default=0.0, metadata=quantity("m/s^2", kind="gravity"))  # g [m/s^2], along −y
    # height of the centre with zero potential energy [m]
    datum_y: float = field(default=0.0, metadata=quantity("m", kind="position"))
    damping: float = field(default=0.0, metadata=quantity("N s/m", kind="damping"))  # d [N s/m] at the centre of mass

    def problems(self) -> list[tuple[str, str]]:
        centre = ("x0", "y0", "vx0", "vy0")
        if self.pivot == "A":
            return [(key, "a pivoted link's centre follows from the pivot and angle0; remove it")
                    for key in centre if getattr(self, key) is not None]
        return [(key, "missing; expected the free link's centre of mass state [m, m/s]")
                for key in centre if getattr(self, key) is None]

    @property
    def points(self) -> tuple[str, ...]:
        return tuple(POINT_OFFSETS)

    def linear_problem(self) -> str | None:
        """Why the model is not linear and time-invariant: a rotating link never is."""
        return "the equations of motion of a rotating link are nonlinear in its angle"

    def drive_problem(self, point: str, drive: str, axes: int) -> str | None:
        """Why ``point`` cannot be a joint side with this drive (None: it can)."""
        if self.pivot == point:
            return "is the ground pivot and does not move"
        if self.pivot != "none" and drive == "displacement":
            return (f"a link turning about a ground pivot has one degree of freedom; a displacement drive "
                    f"prescribes {axes} components of the point's acceleration (over-determined)")
        return None


class PlanarLinkModel:
    """The dynamics, joint outputs, energy and projection of one link (module docstring)."""

    name = "planar_link"
    second_order = True  # z = [q, q']
    point_dimension = 2  # points move in the plane
    coupling_roles = frozenset()  # rigid joints only (no force-displacement coupling elements)
    provides_force = False
    starts_at_rest = False

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> LinkSpec | None:
        return read_table(LinkSpec, table, key, problems)

    def __init__(self, spec: LinkSpec, attachments: Attachments = Attachments()) -> None:
        extra = [part for part in ("terminals", "force_inputs", "motion_outputs", "force_outputs", "effects")
                 if getattr(attachments, part)]
        if extra:
            raise ValueError(f"a planar link takes rigid joints only, got {', '.join(extra)}")
        self.spec = spec
        m, half = spec.mass, 0.5 * spec.length
        self.pinned = spec.pivot == "A"
        self.n_dof = 1 if self.pinned else 3
        self.M = np.array([[spec.inertia + m * half ** 2]]) if self.pinned else np.diag([m, m, spec.inertia])
        self._mass_inverse = 1.0 / np.diag(self.M)  # M is diagonal
        self.sides = attachments.joint_sides
        self.inputs: tuple[Port, ...] = tuple(Port(p, "force" if side.drive == "force" else "acceleration")
                                              for side in self.sides for p in side.inputs)
        ports = []
        for side in self.sides:
            for names, quantity_name in ((side.positions, "position"), (side.velocities, "velocity"),
                                         (side.accelerations, "acceleration"), (side.forces, "force"),
                                         (side.inverse_masses, "inverse_mass")):
                feedthrough = quantity_name in ("acceleration", "force")
                ports += [Port(name, quantity_name, feedthrough=feedthrough) for name in names]
        self.outputs: tuple[Port, ...] = tuple(ports) + (Port("energy", "energy"),)
        self.effects: tuple[str, ...] = tuple(name for name, active in (
            ("gravity", spec.gravity != 0.0), ("damping", spec.damping != 0.0), ("pivot", self.pinned)) if active)
        self._offsets = [POINT_OFFSETS[side.point] * spec.length for side in self.sides]
        self._driven = [i for i, side in enumerate(self.sides) if side.drive == "displacement"]

    def initial_state(self) -> np.ndarray:
        """``z0 = [q, q']``."""
        s = self.spec
        if self.pinned:
            return np.array([s.angle0, s.angular_velocity0])
        return np.array([s.x0, s.y0, s.angle0, s.vx0, s.vy0, s.angular_velocity0])

    # -- kinematics ------------------------------------------------------------------------------------
    def _point(self, q: np.ndarray, qd: np.ndarray, offset: float):
        """Position, velocity, Jacobian ``G`` (2 × n) and bias acceleration ``Ġ q'`` of the point ``offset``
        [m] from S along the link; a pivoted link's coordinates hold the pivot fixed, a free one's S."""
        cos, sin, omega = math.cos(q[-1]), math.sin(q[-1]), qd[-1]
        if self.pinned:
            lever = offset + 0.5 * self.spec.length
            G = np.array([[-lever * sin], [lever * cos]])
            position = np.array([self.spec.pivot_x + lever * cos, self.spec.pivot_y + lever * sin])
        else:
            lever = offset
            G = np.array([[1.0, 0.0, -offset * sin], [0.0, 1.0, offset * cos]])
            position = np.array([q[0] + offset * cos, q[1] + offset * sin])
        return position, G @ qd, G, np.array([-lever * omega ** 2 * cos, -lever * omega ** 2 * sin])

    def sketch(self, z: np.ndarray, w: np.ndarray) -> Sketch:
        """The link as a segment from A to B; its joint points are its anchors."""
        n = self.n_dof
        q, qd = z[:n], z[n:]
        half = 0.5 * self.spec.length
        sketch = Sketch()
        sketch.path("link", self._point(q, qd, -half)[0], self._point(q, qd, half)[0])
        for side, offset in zip(self.sides, self._offsets):
            sketch.anchor(side.point, self._point(q, qd, offset)[0])
        return sketch

    def _centre_height(self, q: np.ndarray) -> float:
        return self.spec.pivot_y + 0.5 * self.spec.length * math.sin(q[0]) if self.pinned else q[1]

    def _applied(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Generalised force of gravity ``(0, −m g)`` and of the damper ``−d v_S`` at the centre of mass."""
        s = self.spec
        if self.pinned:
            half = 0.5 * s.length
            return np.array([-s.mass * s.gravity * half * math.cos(q[0]) - s.damping * half ** 2 * qd[0]])
        return np.array([-s.damping * qd[0], -s.mass * s.gravity - s.damping * qd[1], 0.0])

    def _solve(self, z: np.ndarray, w: np.ndarray):
        """``q''``, the joint points' kinematics and the forces ``F_D`` of displacement-driven sides.

        ``M`` is diagonal; the saddle-point system of the driven sides is solved by its Schur complement
        ``G_D M⁻¹ G_Dᵀ F_D = ã* − Ġ_D q' − G_D M⁻¹ rhs``."""
        n = self.n_dof
        q, qd = z[:n], z[n:]
        points = [self._point(q, qd, offset) for offset in self._offsets]
        rhs = self._applied(q, qd)
        inputs = w.reshape(len(self.sides), 2) if self.sides else np.empty((0, 2))
        for side, (_, _, G, _), value in zip(self.sides, points, inputs):
            if side.drive == "force":
                rhs += G.T @ (side.sign * value)
        if not self._driven:
            return self._mass_inverse * rhs, points, {}
        G_D = np.vstack([points[i][2] for i in self._driven])
        target = np.concatenate([inputs[i] - points[i][3] for i in self._driven])
        forces = np.linalg.solve((G_D * self._mass_inverse) @ G_D.T, target - G_D @ (self._mass_inverse * rhs))
        qdd = self._mass_inverse * (rhs + G_D.T @ forces)
        return qdd, points, {i: forces[2 * j:2 * j + 2] for j, i in enumerate(self._driven)}

    # -- the model interface ---------------------------------------------------------------------------
    def acceleration(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return self._solve(z, w)[0]

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Per joint side: position, velocity, acceleration, joint force (sign of side 1), G M⁻¹ Gᵀ; energy."""
        n = self.n_dof
        qdd, points, forces = self._solve(z, w)
        inputs = w.reshape(len(self.sides), 2) if self.sides else np.empty((0, 2))
        values = []
        for i, (side, (position, velocity, G, bias)) in enumerate(zip(self.sides, points)):
            force = inputs[i] if side.drive == "force" else side.sign * forces[i]
            values += [position, velocity, G @ qdd + bias, force, ((G * self._mass_inverse) @ G.T).ravel()]
        qd = z[n:]
        energy = 0.5 * qd @ self.M @ qd + self.spec.mass * self.spec.gravity * (self._centre_height(z[:n]) - self.spec.datum_y)
        return np.concatenate(values + [[energy]])

    def project(self, z: np.ndarray, corrections: np.ndarray) -> None:
        """Projection step (paper 003 Eqs. 30, 55), this link's part: per joint side, the position and
        velocity corrections ``[ν_x (2), ν_v (2)]`` at the point change the state by ``M⁻¹ Gᵀ ν`` (the
        least change in the metric of M that moves the point by ``G M⁻¹ Gᵀ ν``, to first order)."""
        n = self.n_dof
        for offset, (nu_x, nu_v) in zip(self._offsets, corrections.reshape(len(self.sides), 2, 2)):
            z[:n] += self._mass_inverse * (self._point(z[:n], z[n:], offset)[2].T @ nu_x)
            z[n:] += self._mass_inverse * (self._point(z[:n], z[n:], offset)[2].T @ nu_v)
