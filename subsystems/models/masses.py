"""Point masses on a line with springs, dampers and external forces (the papers' oscillators).

Equations of motion (paper 000 Eq. 3, per subsystem)::

    M x'' = -K_xx x - C_xx v  -  K_xt x*  -  C_xt v*  +  B_f f*  +  f_e(t)  +  f_nl(x, v, x*, v*)

where ``x*, v*`` are the positions and velocities of the *terminals* (remote bodies whose motion
arrives as inputs, paper 000 Fig. 2), ``f*`` the input forces and ``f_e`` the external forces. The
stiffness and damping matrices are stamped over the point coordinates ``q = [x, x*]`` by the linear
effects the scene names; nonlinear two-point effects (paper 002 Eqs. 22–23) add ``f_nl``, evaluated
from their force laws only when the scene names one, so a linear scene runs the matrix products
alone. Effects the scene does not name, or names with a zero coefficient, are not built.

Compensation feedback terms (``subsystems.effects.feedback``, attached by the eigenstructure
compensator) act in the dynamics only: ``(M + D_fb) x'' = ... - K_fb q - C_fb q'`` over
``q = [x, x*]``, the acceleration gains as an added mass (solved exactly at every evaluation;
the acceleration of a terminal is not available, so a terminal source may not have one). The
reported energy stays the physical one. A ``RelayedForce`` adds the force such terms exert on a
terminal to a force output, divided by the sign with which the remote side applies it.

A body can be one side of a rigid joint (paper 003 §2, ``subsystems.ports.JointSide``): force-driven,
the joint force ``λ*`` enters ``f*`` with the side's sign; displacement-driven, the body follows the
received acceleration ``ã*`` and the model reports the force ``μ`` that this takes (Eqs. 33b, 57).

Public matrices (the exact discrete analysis, ``manager.analysis.discrete``, is built from them), with
``z = [x, v]`` and ``w`` the input values in port order:

* ``A_a`` (n × 2n), ``B_a`` (n × n_inputs): ``a = A_a z + B_a w + (M + D_fb)⁻¹ (E f_e(t) + f_nl)``;
* ``C_y`` (k × 2n), ``D_y`` (k × n_inputs): the linear part of the ``k`` outputs other than the
  energy, ``y = C_y z + D_y w`` (+ the nonlinear elements' forces).

They are the whole model when ``nonlinear`` is false.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from zencosim.subsystems.effects import PlacedEffect, read_effect
from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import Attachments, Port
from zencosim.subsystems.sketch import BOX, LANE, Sketch


@dataclass(frozen=True)
class Body:
    """A point mass and its initial state."""

    mass: float = field(metadata=quantity("kg", kind="mass"))  # m [kg]
    x0: float = field(default=0.0, metadata=quantity("m", kind="position"))  # initial position [m]
    v0: float = field(default=0.0, metadata=quantity("m/s", kind="velocity"))  # initial velocity [m/s]


@dataclass(frozen=True)
class MassesSpec:
    """The bodies and effects one subsystem's scene table declares."""

    bodies: dict[str, Body]
    effects: tuple[PlacedEffect, ...]

    @property
    def points(self) -> tuple[str, ...]:
        """Names couplings may attach to."""
        return tuple(self.bodies)

    def drive_problem(self, point: str, drive: str, axes: int) -> str | None:
        """Why ``point`` cannot be a joint side with this drive (None: it can; a point mass always can)."""
        return None

    def linear_problem(self) -> str | None:
        """Why the model is not linear and time-invariant (None: it is)."""
        reasons = {"external": "a force of time", "nonlinear": "nonlinear"}
        found = [f"effect {e.name} is {reasons[e.effect.kind]}" for e in self.effects if e.effect.kind in reasons]
        return "; ".join(found) or None


class MassesModel:
    """A subsystem of point masses: the dynamics, outputs and energy of paper 000 Eq. 3 / paper 002 Fig. 7."""

    name = "masses"
    second_order = True  # the state is z = [x, v]
    point_dimension = 1  # points move on a line: coupling signals are scalars
    coupling_roles = frozenset({"force", "motion"})
    provides_force = False  # a coupling force needs a coupling element (effects)
    starts_at_rest = False

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> MassesSpec | None:
        """Read ``bodies.<name>`` and ``effects.<name>`` of a subsystem table."""
        before = len(problems)
        bodies_table = table.get("bodies")
        bodies: dict[str, Body] = {}
        if not isinstance(bodies_table, dict) or not bodies_table:
            problems.add(f"{key}.bodies", "expected a table of bodies, e.g. bodies.m1 = { mass = 1.0 }")
        else:
            for body_name, body_table in bodies_table.items():
                body = read_table(Body, body_table, f"{key}.bodies.{body_name}", problems)
                if body is not None:
                    bodies[body_name] = body
        effects = []
        effects_table = table.get("effects", {})
        if not isinstance(effects_table, dict):
            problems.add(f"{key}.effects", "expected a table of named effects")
            effects_table = {}
        for effect_name, effect_table in effects_table.items():
            effect_key = f"{key}.effects.{effect_name}"
            effect = read_effect(effect_table, effect_key, problems)
            if effect is None:
                continue
            if getattr(effect, "free_length", 0.0) != 0.0:
                problems.add(f"{effect_key}.free_length", "expected 0 for points on a line (a free length "
                             "needs points in the plane)")
                continue
            endpoints = effect_table.get("bodies", [])
            if (not isinstance(endpoints, list) or len(endpoints) not in effect.endpoint_counts
                    or any(not isinstance(b, str) for b in endpoints)):
                counts = " or ".join(str(c) for c in effect.endpoint_counts)
                problems.add(f"{effect_key}.bodies", f"expected an array of {counts} body names, got {endpoints!r}")
                continue
            declared = bodies_table if isinstance(bodies_table, dict) else {}
            for body_name in endpoints:
                if body_name not in declared:
                    problems.add(f"{effect_key}.bodies", f"unknown body {body_name!r}; "
                                 f"expected one of {', '.join(declared)}")
            padded = tuple(endpoints) + (None,) * (max(effect.endpoint_counts) - len(endpoints))
            effects.append(PlacedEffect(effect_name, effect, padded))
        unknown = sorted(set(table) - {"bodies", "effects"})
        for extra in unknown:
            problems.add(f"{key}.{extra}", "unknown key; expected bodies or effects")
        if len(problems) != before:
            return None
        return MassesSpec(bodies, tuple(effects))

    def __init__(self, spec: MassesSpec, attachments: Attachments = Attachments()) -> None:
        self.body_names = tuple(spec.bodies)
        self.n_dof = len(self.body_names)
        self.inputs: tuple[Port, ...] = _input_ports(self.name, attachments)
        placed = [e for e in spec.effects + tuple(PlacedEffect(*t) for t in attachments.effects) if e.effect.active()]
        self.effects: tuple[str, ...] = tuple(e.name for e in placed)
        layout = _Layout(self.body_names, attachments.terminals, self.inputs, {e.name: e for e in placed})
        # nonlinear two-point elements: (effect, coordinates of a, of b, body index of a, of b)
        self._nonlinear = tuple(
            (e.effect, layout.coordinates(e.endpoints[0]), layout.coordinates(e.endpoints[1]),
             *(layout.point_index[p] if p is not None and layout.point_index[p] < layout.n else None for p in e.endpoints))
            for e in placed if e.effect.kind == "nonlinear")
        # two-point elements among the bodies and the ground, as drawn: (name, spring?, body a, body b or ground)
        self._drawn = tuple((e.name, "spring" in type(e.effect).__name__.lower(), *ends)
                            for e in placed if e.effect.kind in ("linear", "nonlinear")
                            for ends in [[layout.point_index[p] if p is not None else None for p in e.endpoints]]
                            if all(i is None or i < layout.n for i in ends))
        forces = self._build_dynamics(spec, attachments, layout, placed)
        rows = self._build_outputs(attachments, layout, placed, forces)
        self._build_energy(layout, rows, forces)
        self._z0 = np.array([spec.bodies[b].x0 for b in self.body_names] + [spec.bodies[b].v0 for b in self.body_names],
                            dtype=np.float64)

    def _build_dynamics(self, spec: MassesSpec, attachments: Attachments, layout: "_Layout",
                        placed: list) -> "_Forces":
        """``M, K, C`` and ``a = A_a z + B_a w + (M + D_fb)⁻¹ (E f_e(t) + f_nl)``."""
        n, terminals, point_index, input_index = layout.n, layout.terminals, layout.point_index, layout.input_index
        Kq, Cq = layout.stamped(placed)
        Mf, Kf, Cf = layout.feedback_stamped(placed)
        self.M = np.diag([spec.bodies[b].mass for b in self.body_names])
        self.K = Kq[:n, :n].copy()  # stiffness among the bodies [N/m]
        self.C = Cq[:n, :n].copy()  # damping among the bodies [N s/m]
        M_eff = self.M + Mf[:n, :n]  # with the added mass of acceleration feedback [kg]
        if np.linalg.cond(M_eff) > 1e12:
            raise ValueError(f"the effective mass M + D_fb is singular (condition number {np.linalg.cond(M_eff):.3g}); "
                             "expected acceleration feedback that leaves the bodies some inertia")
        Minv = np.linalg.inv(M_eff)

        # f = A_f z + B_w w + E f_e(t)  with  z = [x, v],  w = input values
        A_f = np.hstack((-self.K - Kf[:n, :n], -self.C - Cf[:n, :n]))
        B_w = np.zeros((n, layout.n_in))
        for j, t in enumerate(terminals):
            B_w[:, input_index[t.position_inputs[0]]] = -Kq[:n, n + j] - Kf[:n, n + j]
            B_w[:, input_index[t.velocity_inputs[0]]] = -Cq[:n, n + j] - Cf[:n, n + j]
        for f in attachments.force_inputs:
            B_w[point_index[f.point], input_index[f.ports[0]]] += f.sign
        joints = [(side, point_index[side.point], input_index[side.inputs[0]]) for side in attachments.joint_sides]
        if joints and np.any(Mf):
            raise ValueError("a joint side needs the bodies' own mass matrix: acceleration feedback would couple a "
                             "displacement-driven body to the others")
        for side, i, column in joints:
            if side.drive == "force":
                B_w[i, column] += side.sign
        self.A_a = Minv @ A_f
        self.B_a = Minv @ B_w
        self._inverse_mass = Minv  # of the nonlinear elements' forces (diagonal unless acceleration feedback)
        self.external = tuple((e.effect, point_index[e.endpoints[0]]) for e in placed if e.effect.kind == "external")
        self._E_a = Minv[:, [body for _, body in self.external]]
        self._driven = [i for side, i, _ in joints if side.drive == "displacement"]
        for side, i, column in joints:
            if side.drive == "displacement":  # the body follows the received acceleration
                self.A_a[i], self.B_a[i], self._E_a[i] = 0.0, np.eye(layout.n_in)[column], 0.0
        return _Forces(joints, Kq, A_f, B_w)

    def _relayed_force(self, relay, layout: "_Layout") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The force the relayed feedback terms exert on the terminal, on z, w and f_e."""
        n = layout.n
        Mr, Kr, Cr = layout.feedback_stamped([layout.by_name[name] for name in relay.effects if name in layout.by_name])
        i = layout.point_index[relay.terminal]
        row_z = -np.concatenate((Kr[i, :n], Cr[i, :n])) - Mr[i, :n] @ self.A_a
        row_w = -Mr[i, :n] @ self.B_a
        for j, t in enumerate(layout.terminals):
            row_w[layout.input_index[t.position_inputs[0]]] -= Kr[i, n + j]
            row_w[layout.input_index[t.velocity_inputs[0]]] -= Cr[i, n + j]
        return row_z / relay.sign, row_w / relay.sign, -Mr[i, :n] @ self._E_a / relay.sign

    def _build_outputs(self, attachments: Attachments, layout: "_Layout", placed: list, forces: "_Forces") -> "_Rows":
        """Rows of the linear outputs ``y = C_y z + D_y w (+ F_y f_e(t))``: motion outputs, force outputs, then
        the joint sides' outputs."""
        rows = _Rows(layout, len(self.external))
        for m in attachments.motion_outputs:
            i = layout.point_index[m.point]
            rows.add(Port(m.position_ports[0], "position"), np.eye(2 * layout.n)[i])
            rows.add(Port(m.velocity_ports[0], "velocity"), np.eye(2 * layout.n)[layout.n + i])
        self._add_force_outputs(attachments, layout, placed, rows)
        self._add_joint_outputs(layout, forces, rows)
        return rows

    def _add_force_outputs(self, attachments: Attachments, layout: "_Layout", placed: list, rows: "_Rows") -> None:
        """Each coupling force: the force its coupling effects exert on the remote point (the reaction of their
        force on the output's own point), plus relayed feedback terms."""
        n, n_in, point_index, input_index = layout.n, layout.n_in, layout.point_index, layout.input_index
        unknown = {r.port for r in attachments.relayed_forces} - {out.ports[0] for out in attachments.force_outputs}
        if unknown:
            raise ValueError(f"relayed forces name outputs {sorted(unknown)}; expected force outputs of this subsystem")
        nonlinear_index = {e.name: k for k, e in enumerate(e for e in placed if e.effect.kind == "nonlinear")}
        self._nonlinear_outputs = []  # (output row, nonlinear element, sign of its force's reaction on the point)
        for out in attachments.force_outputs:
            Ke, Ce = layout.stamped([layout.by_name[name] for name in out.effects if name in layout.by_name])
            i = point_index[out.point]
            row_z = np.concatenate((Ke[i, :n], Ce[i, :n]))
            row_w = np.zeros(n_in)
            for j, t in enumerate(layout.terminals):
                row_w[input_index[t.position_inputs[0]]] = Ke[i, n + j]
                row_w[input_index[t.velocity_inputs[0]]] = Ce[i, n + j]
            row_f = np.zeros(rows.n_external)
            for relay in attachments.relayed_forces:
                if relay.port == out.ports[0]:
                    relayed = self._relayed_force(relay, layout)
                    row_z, row_w, row_f = row_z + relayed[0], row_w + relayed[1], row_f + relayed[2]
            through_elements = []  # the inputs of the nonlinear elements' terminals (their forces are not in row_w)
            for name in out.effects:
                if name in nonlinear_index:
                    endpoints = layout.by_name[name].endpoints
                    self._nonlinear_outputs.append((len(rows.ports), nonlinear_index[name],
                                                    -1.0 if endpoints[0] == out.point else 1.0))
                    through_elements += [port for p in endpoints if p is not None and point_index[p] >= n
                                         for port in layout.terminal_inputs(p)]
            rows.add(Port(out.ports[0], "force"), row_z, row_w, row_f, through=tuple(through_elements))

    def _add_joint_outputs(self, layout: "_Layout", forces: "_Forces", rows: "_Rows") -> None:
        """Per joint side: position, velocity, acceleration, force ``f = sign × (joint force on the body)``, 1/m.
        The acceleration and force carry external forces (rows of ``F_y``) and nonlinear element forces
        (``_joint_nonlinear``); 1/m is a constant."""
        n, n_in = layout.n, layout.n_in
        self._joint_nonlinear = []
        E_f = np.eye(n)[:, [body for _, body in self.external]]  # external forces onto bodies
        for side, i, column in forces.joints:
            mass = self.M[i, i]
            if side.drive == "force":
                f_z, f_w, f_e = np.zeros(2 * n), np.eye(n_in)[column], None
                self._joint_nonlinear.append((len(rows.ports) + 2, i, 1.0 / mass))  # a += f_nl / m
            else:  # μ = sign (m ã* − forces of the subsystem on the body)
                f_z = -side.sign * forces.A_f[i]
                f_w = side.sign * (mass * np.eye(n_in)[column] - forces.B_w[i])
                f_e = -side.sign * E_f[i]
                self._joint_nonlinear.append((len(rows.ports) + 3, i, -side.sign))  # μ −= sign f_nl
            rows.add(Port(side.positions[0], "position"), np.eye(2 * n)[i])
            rows.add(Port(side.velocities[0], "velocity"), np.eye(2 * n)[n + i])
            rows.add(Port(side.accelerations[0], "acceleration"), self.A_a[i], self.B_a[i], self._E_a[i])
            rows.add(Port(side.forces[0], "force"), f_z, f_w, f_e)
            rows.add(Port(side.inverse_masses[0], "inverse_mass"), np.zeros(2 * n), constant=1.0 / mass)

    def _build_energy(self, layout: "_Layout", rows: "_Rows", forces: "_Forces") -> None:
        """The output ports with the energy ``0.5 s^T Q s`` last (``s = [x, v, w]``), and the one matrix ``_G``
        whose product with ``s`` gives the linear outputs and ``Q s``."""
        n, n_in, ports = layout.n, layout.n_in, rows.ports
        self._joint_bodies = tuple((i, self.M[i, i]) for _, i, _ in forces.joints)
        self._y_constant = np.array(rows.constants) if forces.joints else None
        self.outputs: tuple[Port, ...] = tuple(ports) + (Port("energy", "energy"),)
        Q = np.zeros((2 * n + n_in, 2 * n + n_in))
        q_index = list(range(n)) + [2 * n + layout.input_index[t.position_inputs[0]] for t in layout.terminals]
        Q[np.ix_(q_index, q_index)] = forces.Kq
        Q[n:2 * n, n:2 * n] = self.M
        # one product gives the linear outputs and Q s:  [C_y D_y; Q/2] s
        self._n_linear = len(ports)
        self._G = np.vstack((np.hstack((np.array(rows.z).reshape(len(ports), 2 * n),
                                        np.array(rows.w).reshape(len(ports), n_in))), 0.5 * Q))
        self.C_y = self._G[:self._n_linear, :2 * n]
        self.D_y = self._G[:self._n_linear, 2 * n:]
        F_y = np.array(rows.F_y).reshape(len(ports), len(self.external))
        self._F_y = F_y if np.any(F_y) else None

    def initial_state(self) -> np.ndarray:
        """``z0 = [x0, v0]``."""
        return self._z0.copy()

    @property
    def nonlinear(self) -> bool:
        """True when a nonlinear effect is built (the matrices M, C, K then do not describe the model)."""
        return bool(self._nonlinear)

    def acceleration(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``a = (M + D_fb)⁻¹ (A_f z + B_w w + E f_e(t) + f_nl)`` at time t [s] (displacement-driven
        bodies of a joint: ``ã*``)."""
        a = self.A_a.dot(z) + self.B_a.dot(w)
        if self.external:
            a = a + self._E_a.dot([effect.force(t) for effect, _ in self.external])
        if self._nonlinear:
            f = self._body_forces(np.concatenate((z, w)))
            f[self._driven] = 0.0
            a = a + self._inverse_mass.dot(f)
        return a

    def _body_forces(self, s: np.ndarray) -> np.ndarray:
        """The nonlinear elements' forces summed onto each body at ``s = [x, v, w]``."""
        f = np.zeros(self.n_dof)
        for (_, _, _, body_a, body_b), force in zip(self._nonlinear, self._element_forces(s)):
            if body_a is not None:
                f[body_a] += force
            if body_b is not None:
                f[body_b] -= force
        return f

    def linear_dynamics(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A_a, B_a)`` for integrators that need a linear, time-invariant model (``exact``)."""
        if self.external or self._nonlinear:
            raise ValueError("the model has external forces of time or nonlinear effects")
        return self.A_a, self.B_a

    def _element_forces(self, s: np.ndarray) -> list[float]:
        """Force law of every nonlinear element at ``s = [x, v, w]`` (on its point a)."""
        forces = []
        for effect, a, b, _, _ in self._nonlinear:
            elongation, rate = (s[a[0]] - s[b[0]], s[a[1]] - s[b[1]]) if b is not None else (s[a[0]], s[a[1]])
            forces.append(effect.force(float(elongation), float(rate)))
        return forces

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Coupling outputs followed by the mechanical energy [J] of the subsystem (incl. its coupling springs)."""
        return self.outputs_of(t, np.concatenate((z, w)))

    def output_matrix(self) -> tuple[np.ndarray, int, np.ndarray | None]:
        """``(G, k, y_0)`` of a linear, time-invariant model (``linear_dynamics``): its ``k`` linear outputs are
        ``G[:k] s + y_0`` (``y_0`` None: no constant) and its energy ``s · G[k:] s``, ``s = [z, w]``: the products
        ``outputs_of`` makes, for ``subsystems.straight_line``."""
        return self._G, self._n_linear, self._y_constant

    def outputs_of(self, t: float, s: np.ndarray) -> np.ndarray:
        """``outputs_at`` of ``s = [z, w]`` (a subsystem keeps its linear state in such a vector)."""
        r = self._G.dot(s)
        k = self._n_linear
        y = r[:k + 1]
        y[k] = r[k:].dot(s)  # energy 0.5 s^T Q s [J]
        if self._F_y is not None:
            y[:k] += self._F_y.dot([effect.force(t) for effect, _ in self.external])
        if self._nonlinear:
            forces = self._element_forces(s)
            for row, element, sign in self._nonlinear_outputs:
                y[row] += sign * forces[element]
            for effect, a, b, _, _ in self._nonlinear:
                y[k] += effect.potential(float(s[a[0]] - (s[b[0]] if b is not None else 0.0)))
        if self._y_constant is not None:
            y[:k] += self._y_constant
            if self._nonlinear:
                f = self._body_forces(s)
                for row, body, factor in self._joint_nonlinear:
                    y[row] += factor * f[body]
        return y

    def outputs_of_rows(self, t: np.ndarray, S: np.ndarray) -> np.ndarray:
        """``outputs_of`` of every row of ``S`` at the times ``t`` [s], as rows: two matrix products for a linear,
        time-invariant model (equal to ``outputs_of`` row by row up to rounding), else row by row."""
        if self._F_y is not None or self._nonlinear:
            return np.array([self.outputs_of(time, s) for time, s in zip(t, S)])
        R = S.dot(self._G.T)
        k = self._n_linear
        Y = R[:, :k + 1]
        Y[:, k] = np.einsum("ij,ij->i", R[:, k:], S)  # energy 0.5 s^T Q s [J]
        if self._y_constant is not None:
            Y[:, :k] += self._y_constant
        return Y

    def sketch(self, z: np.ndarray, w: np.ndarray) -> Sketch:
        """Each body a box on a lane of its own (``subsystems.sketch``), each spring a zigzag and each damper
        a line beside it, to the other body or to the ground at x = 0 under the lane."""
        sketch = Sketch(on_line=True)
        centers = [(float(z[i]), -i * LANE) for i in range(self.n_dof)]
        for name, center in zip(self.body_names, centers):
            sketch.box(name, center)
            sketch.anchor(name, center)
        for name, spring, a, b in self._drawn:
            start = centers[a]
            end = centers[b] if b is not None else (0.0, start[1] - 0.5 * LANE)
            if spring:
                sketch.spring(name, start, end)
            else:
                sketch.path(name, (start[0], start[1] + BOX / 2), (end[0], end[1] + BOX / 2))
        return sketch

    def project(self, z: np.ndarray, corrections: np.ndarray) -> None:
        """Projection step (paper 003 Eqs. 30, 55, 68), this subsystem's part: the position and velocity
        corrections ``[ν_x, ν_v]`` of each joint side (an impulse-like correction at the point) move the
        body by ``ν / m`` (``M⁻¹ Gᵀ ν`` for a point mass)."""
        n = self.n_dof
        for side, (i, mass) in enumerate(self._joint_bodies):
            z[i] += corrections[2 * side] / mass
            z[n + i] += corrections[2 * side + 1] / mass


def _input_ports(model: str, attachments: Attachments) -> tuple[Port, ...]:
    """Terminal positions and velocities, force inputs, then the joint sides' inputs; all scalars on a line."""
    terminals = attachments.terminals
    scalar = [t.position_inputs for t in terminals] + [f.ports for f in attachments.force_inputs]
    scalar += [m.position_ports for m in attachments.motion_outputs] + [o.ports for o in attachments.force_outputs]
    if any(len(ports) != 1 for ports in scalar):
        raise ValueError(f"the {model} model moves on a line: coupling signals must be scalars, got {scalar}")
    if any(not o.effects for o in attachments.force_outputs):
        raise ValueError(f"the {model} model computes a coupling force only from coupling effects")
    return tuple(
        [Port(p[0], q) for t in terminals for p, q in ((t.position_inputs, "position"), (t.velocity_inputs, "velocity"))]
        + [Port(f.ports[0], "force") for f in attachments.force_inputs]
        + [Port(p, "force" if j.drive == "force" else "acceleration") for j in attachments.joint_sides for p in j.inputs])


class _Forces(NamedTuple):
    """What the outputs are built from: the joint sides (side, body index, input column), the stiffness over
    ``q`` of every linear effect, and the body forces ``f = A_f z + B_w w`` (without external forces)."""

    joints: list
    Kq: np.ndarray
    A_f: np.ndarray
    B_w: np.ndarray


class _Rows:
    """The linear outputs, one entry per port: ``y = z-row · z + w-row · w + F_y-row · f_e(t) + constant``."""

    def __init__(self, layout: "_Layout", n_external: int) -> None:
        self.n_inputs, self.n_external = layout.n_in, n_external
        self.input_names = tuple(sorted(layout.input_index, key=layout.input_index.get))
        self.z, self.w, self.F_y, self.constants, self.ports = [], [], [], [], []

    def add(self, port: Port, row_z: np.ndarray, row_w: np.ndarray | None = None, row_f: np.ndarray | None = None,
            constant: float = 0.0, through: tuple[str, ...] = ()) -> None:
        """One output (missing rows: zero); it feeds through the inputs its w-row weighs and those ``through``
        names (inputs that act on it beyond the linear rows)."""
        direct = {self.input_names[j] for j in np.flatnonzero(row_w)} if row_w is not None else set()
        direct.update(through)
        depends_on = tuple(name for name in self.input_names if name in direct)
        self.ports.append(dataclasses.replace(port, feedthrough=bool(depends_on), depends_on=depends_on or None))
        self.z.append(row_z)
        self.w.append(np.zeros(self.n_inputs) if row_w is None else row_w)
        self.F_y.append(np.zeros(self.n_external) if row_f is None else row_f)
        self.constants.append(constant)


class _Layout:
    """Where the points and inputs of a masses model sit: bodies ``0..n-1`` then terminals ``n..`` in the
    point coordinates ``q = [x, x*]``, and the stamping of effects into matrices over ``q``."""

    def __init__(self, body_names: tuple[str, ...], terminals: tuple, inputs: tuple[Port, ...],
                 by_name: dict[str, PlacedEffect]) -> None:
        self.n = len(body_names)
        self.terminals = terminals
        self.point_index = {name: i for i, name in enumerate(body_names)}
        self.point_index.update({t.name: self.n + j for j, t in enumerate(terminals)})
        self.input_index = {p.name: j for j, p in enumerate(inputs)}
        self.n_in = len(inputs)
        self.by_name = by_name  # the active effects, in scene order

    def terminal_inputs(self, point: str) -> tuple[str, ...]:
        """The position and velocity inputs of terminal ``point``."""
        t = self.terminals[self.point_index[point] - self.n]
        return (t.position_inputs[0], t.velocity_inputs[0])

    def coordinates(self, point: str | None) -> tuple[int, int] | None:
        """Indices of a point's position and velocity in ``s = [x, v, w]`` (None: the ground)."""
        if point is None:
            return None
        i = self.point_index[point]
        if i < self.n:
            return i, self.n + i
        t = self.terminals[i - self.n]
        return 2 * self.n + self.input_index[t.position_inputs[0]], 2 * self.n + self.input_index[t.velocity_inputs[0]]

    def indices(self, e: PlacedEffect) -> list[int | None]:
        return [None if p is None else self.point_index[p] for p in e.endpoints]

    def stamped(self, selection: list[PlacedEffect]) -> tuple[np.ndarray, np.ndarray]:
        """Stiffness and damping over ``q`` of the linear effects of ``selection``."""
        size = self.n + len(self.terminals)
        K, C = np.zeros((size, size)), np.zeros((size, size))
        for e in selection:
            if e.effect.kind == "linear":
                e.effect.stamp(K, C, *self.indices(e))
        return K, C

    def feedback_stamped(self, selection: list[PlacedEffect]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Acceleration, position and velocity gains over ``q`` of the feedback effects of ``selection``."""
        size = self.n + len(self.terminals)
        Mf, Kf, Cf = np.zeros((size, size)), np.zeros((size, size)), np.zeros((size, size))
        for e in selection:
            if e.effect.kind == "feedback":
                target, source = self.indices(e)
                if source >= self.n and e.effect.acceleration_gain != 0.0:
                    raise ValueError(f"feedback {e.name}: expected the acceleration of a body of this subsystem, "
                                     f"got terminal {e.endpoints[1]} (its acceleration is not an input)")
                e.effect.stamp(Mf, Kf, Cf, target, source)
        return Mf, Kf, Cf
