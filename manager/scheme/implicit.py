"""Implicit predictor/corrector co-simulation with rollback over the bus (paper 003 §2).

One rigid joint between two subsystems, coupled by one of the paper's methods (Baumgarte, weighted
multiplier, projection) on one of its decompositions. Like ``manager.scheme.jacobi`` the scheme is a
generator that yields :class:`Exchange` requests to a bus, so both buses run the same arithmetic.

Initialisation (t_0): the coupling variables ``e_0`` that zero the joint's acceleration-level and force
conditions (index-1 consistent), from the subsystems' outputs at two sets of INIT inputs.

One macro-step T_N → T_{N+1} (k = ``manager.extrapolation``):

1. SAVE every subsystem at T_N;
2. predictor: STEP with the Lagrange polynomial through ``e_N ... e_{N-k}`` (Eq. 9) → outputs ``y^p``;
3. derivatives of the outputs at T_{N+1} w.r.t. the corrector value ``e*_{N+1}`` (Eqs. 13, 39, 63):
   forward differences over RESTORE + STEP with the corrector polynomial through
   ``e^p + δ, e_N, ..., e_{N-k+1}`` (Eq. 11); variables that drive different subsystems are perturbed
   in the same round. No subsystem gives them analytically: the finite difference is exact up to
   rounding for linear subsystems, and the step δ is chosen in ``sensitivity_steps``;
4. coupling law ``compensation.implicit.coupling_laws.corrected_coupling`` → ``e_{N+1}``;
5. corrector: RESTORE + STEP through ``e_{N+1}, e_N, ...``. For linear subsystems one corrector run
   is exact (§2.1.1, end). With ``max_iterations > 1`` (nonlinear subsystems) the method's law is
   applied again at the corrector's outputs with the same derivatives (a chord Newton iteration) and
   the corrector repeated until ``e`` changes by less than ``tolerance`` relative;
6. projection method only: PROJECT both sides onto the joint (Eqs. 30, 55, 68), weighted by the
   points' inverse effective masses.

A subsystem that cannot save or restore (it answers with an error) ends the run, named. A diverging
method stops the run at the first macro-step whose joint opens wider than ``divergence_gap`` (or whose
values are not finite), long before floating-point overflow; the rest of the record is NaN.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Generator

import numpy as np

from zencosim.compensation.implicit.coupling_laws import CouplingMethod, corrected_coupling
from zencosim.compensation.implicit.decompositions import Decomposition
from zencosim.compensation.lagrange_polynomials import extrapolation_weights
from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scene.couplings import RigidJoint
from zencosim.manager.scene.load import Scene
from zencosim.manager.scene.settings import ImplicitSettings
from zencosim.manager.scheme.base import (
    HISTORY_ROWS,
    PROGRESS_EVERY,
    Exchange,
    ImplicitRecord,
    RunRecord,
    decode_output,
    expect_reply,
)
from zencosim.manager.scheme.extrapolation import lagrange_coefficients
from zencosim.manager.scheme.pacing import Releases
from zencosim.manager.scheme.window import RowWindow, Spill
from zencosim.manager.wire.protocol import Kind, encode
from zencosim.manager.wire.status import StatusReport

LEVELS = ("positions", "velocities", "accelerations", "forces")  # output levels of a joint side, in law order


@dataclass(frozen=True)
class JointPlan:
    """Indices of one rigid joint in the run plan: who receives which coupling variable, who reports what."""

    decomposition: Decomposition
    method: CouplingMethod  # parameters in SI units
    k: int  # degree of the predictor and corrector polynomials (manager.extrapolation)
    axes: int
    sides: tuple[int, int]  # subsystem index of side 1 and side 2
    outputs: tuple[np.ndarray, np.ndarray]  # per side (4, axes): output index of x, v, a, f
    inverse_mass: tuple[np.ndarray, np.ndarray]  # per side (axes * axes,): output index of G M⁻¹ Gᵀ, row-major
    inputs: tuple[np.ndarray, np.ndarray]  # per side (axes,): input index of each coupling variable it receives
    variables: tuple[np.ndarray, np.ndarray]  # per side (axes,): which coupling variables those are
    n_e: int
    rounds: tuple[tuple[int, ...], ...]  # coupling variables perturbed together (no subsystem receives two)


def compile_joint(scene: Scene, plan: Plan) -> JointPlan:
    """The plan of the scene's one rigid joint (``manager.scene.load`` checked that there is exactly one)."""
    joint = next(c for c in scene.couplings.values() if isinstance(c, RigidJoint))
    variables = joint.coupling_variables()
    sides, outputs, inverse_mass, inputs, received = [], [], [], [], []
    for index in (0, 1):
        side = joint.side(index)
        sub = plan.by_name(joint.points[index][0])
        out = {p.name: j for j, p in enumerate(sub.outputs)}
        into = {p.name: j for j, p in enumerate(sub.inputs)}
        sides.append(sub.index)
        outputs.append(np.array([[out[name] for name in getattr(side, level)] for level in LEVELS]))
        inverse_mass.append(np.array([out[name] for name in side.inverse_masses]))
        inputs.append(np.array([into[name] for name in side.inputs]))
        received.append(np.array([variables.index(name[:-1]) for name in side.inputs]))
    return JointPlan(joint.decomposition, scene.manager.implicit.coupling_method(), scene.manager.extrapolation,
                     joint.dimension, tuple(sides), tuple(outputs), tuple(inverse_mass), tuple(inputs), tuple(received),
                     len(variables), _perturbation_rounds(len(variables), received))


def _perturbation_rounds(n_e: int, received: list[np.ndarray]) -> tuple[tuple[int, ...], ...]:
    """Group the coupling variables so that no side receives two of one group (greedy)."""
    receivers = [{side for side in (0, 1) if j in received[side]} for j in range(n_e)]
    rounds: list[list[int]] = []
    for j in range(n_e):
        for group in rounds:
            if not any(receivers[j] & receivers[i] for i in group):
                group.append(j)
                break
        else:
            rounds.append([j])
    return tuple(tuple(group) for group in rounds)


def sensitivity_steps(coupling: np.ndarray, relative_step: float) -> np.ndarray:
    """Forward-difference steps ``δ_j = relative_step × max(|e_j|, 1)`` (1 in the variable's SI unit: N or
    m/s², below which the step is absolute). Truncation error ∝ δ, rounding error ∝ eps/δ; for the
    subsystems here the outputs are affine in ``e*`` up to O(H²) so the rounding error dominates
    (docs/implicit.md measures both)."""
    return relative_step * np.maximum(np.abs(coupling), 1.0)


class _JointExchanges:
    """The exchanges of one implicit run, around its history ``e_N`` of coupling variables: each is a
    generator that yields :class:`Exchange` requests and returns what the replies say."""

    def __init__(self, plan: Plan, joint: JointPlan, settings: ImplicitSettings, spill: Spill | None = None) -> None:
        self.subs, self.base, self.joint, self.settings = plan.subsystems, plan.base_step_ns, joint, settings
        # e_N, its newest rows (manager.scheme.window); row N + 1 holds the corrector's candidate
        self.history = RowWindow(plan.n_ticks + 1, joint.n_e, float, np.nan, joint.k + 2, spill, "coupling-variables")
        self.side_of = {joint.sides[side]: side for side in (0, 1)}

    def input_rows(self, s: SubsystemPlan, newest: int, offset_ns: int) -> np.ndarray:
        """Input polynomial of ``s``: its coupling variables through history rows ``... newest``."""
        joint = self.joint
        coefficients = np.zeros((joint.k + 1, len(s.inputs)))
        side = self.side_of.get(s.index)
        if side is not None:
            history = self.history
            c = lagrange_coefficients(history.array, joint.variables[side], newest, joint.k, self.base, offset_ns,
                                      history.offset)
            coefficients[:len(c), joint.inputs[side]] = c
        return coefficients

    def side_outputs(self, outputs: dict[int, np.ndarray]) -> np.ndarray:
        """(2, 4, axes): x, v, a, f of each side (``corrected_coupling``'s layout)."""
        return np.array([outputs[self.joint.sides[side]][self.joint.outputs[side]] for side in (0, 1)])

    def control(self, kind: Kind, tick: int, targets: tuple[SubsystemPlan, ...], step_status: bytes | None = None):
        sends = {s.name: encode(kind, tick, tick * self.base) for s in targets}
        replies = yield Exchange(sends, tuple(sends), step_status)
        for s in targets:
            expect_reply(replies[s.name], s, Kind.ACK, tick, kind)

    def run(self, tick: int, targets: tuple[SubsystemPlan, ...], newest: int, offset_ns: int):
        """STEP ``targets`` from ``tick`` with their coupling variables through history row ``newest``."""
        rows = self.joint.k + 1
        sends = {s.name: encode(Kind.STEP, tick, tick * self.base, self.input_rows(s, newest, offset_ns), rows)
                 for s in targets}
        replies = yield Exchange(sends, tuple(sends))
        return {s.index: decode_output(replies[s.name], s, tick + 1) for s in targets}

    def at_start(self, e: np.ndarray, targets: tuple[SubsystemPlan, ...]):
        """Outputs of ``targets`` at t_0 with coupling variables ``e`` (INIT leaves the state alone)."""
        self.history.array[0] = e
        sends = {s.name: encode(Kind.INIT, 0, 0, self.input_rows(s, 0, 0)[:1], rows=1) for s in targets}
        replies = yield Exchange(sends, tuple(sends))
        return {s.index: decode_output(replies[s.name], s, 0) for s in targets}

    def corrector(self, tick: int, e: np.ndarray, targets: tuple[SubsystemPlan, ...]):
        """Outputs of ``targets`` at T_{N+1} from the state saved at T_N, corrector value ``e`` (Eq. 11)."""
        self.history.put(tick + 1, e)
        yield from self.control(Kind.RESTORE, tick, targets)
        return (yield from self.run(tick, targets, tick + 1, -self.base))

    def derivatives(self, outputs: dict[int, np.ndarray], e: np.ndarray, outputs_with):
        """Forward differences (2, 4, axes, n_e) of the side outputs w.r.t. the coupling variables at
        ``e``, where ``outputs`` were computed; ``outputs_with(e, targets)`` computes them again."""
        joint = self.joint
        sensitivity = np.zeros((2, 4, joint.axes, joint.n_e))
        y, delta = self.side_outputs(outputs), sensitivity_steps(e, self.settings.sensitivity_step)
        for group in joint.rounds:
            perturbed = {side: j for side in (0, 1) for j in group if j in joint.variables[side]}
            e_perturbed = e.copy()
            e_perturbed[list(group)] += delta[list(group)]
            again = yield from outputs_with(e_perturbed, tuple(self.subs[joint.sides[side]] for side in perturbed))
            y_perturbed = self.side_outputs({**outputs, **again})
            for side, j in perturbed.items():
                sensitivity[side, :, :, j] = (y_perturbed[side] - y[side]) / delta[j]
        return sensitivity

    def consistent_start(self):
        """The outputs at t_0 with ``e_0`` that zeros the acceleration-level and force conditions (outputs are
        affine in the inputs at t_0)."""
        decomposition, subs = self.joint.decomposition, self.subs
        acceleration_level = (0.0, 0.0, 1.0)
        zero = np.zeros(self.joint.n_e)
        outputs = yield from self.at_start(zero, subs)
        sensitivity = yield from self.derivatives(outputs, zero, self.at_start)
        e0 = decomposition.linearised_conditions(self.side_outputs(outputs), sensitivity).root(zero, acceleration_level)
        # one Newton correction with the residual at e0: the derivatives' rounding error (the steps are set
        # by |e| = 0 here) then only multiplies a residual that is already at rounding level
        y0 = self.side_outputs((yield from self.at_start(e0, subs)))
        e0 = decomposition.linearised_conditions(y0, sensitivity).root(e0, acceleration_level)
        return (yield from self.at_start(e0, subs))

    def corrected(self, tick: int, e_new: np.ndarray, sensitivity: np.ndarray):
        """The corrector runs of macro-step ``tick`` from ``e_new``: once for linear subsystems, else the chord
        Newton iteration up to ``max_iterations`` runs; returns (outputs, last e, runs)."""
        method, decomposition, settings = self.joint.method, self.joint.decomposition, self.settings
        for iteration in range(1, settings.max_iterations + 1):
            corrected = yield from self.corrector(tick, e_new, self.subs)
            if iteration == settings.max_iterations:
                break
            e_next = method.correct(e_new, decomposition.linearised_conditions(self.side_outputs(corrected), sensitivity))
            if np.all(np.abs(e_next - e_new) <= settings.tolerance * np.maximum(np.abs(e_new), 1.0)):
                break
            e_new = e_next
        return corrected, e_new, iteration

    def project(self, y: np.ndarray, outputs: dict[int, np.ndarray], tick: int):
        """Projection step (Eqs. 30, 55, 68): move both points onto each other, in position and velocity.

        With the points' inverse effective masses ``W_i = G_i M_i⁻¹ G_iᵀ``, the correction ``ν`` (an
        impulse-like force at the point) that minimises the mass-weighted change of both states subject to
        ``x_1 + W_1 ν = x_2 − W_2 ν`` is ``ν = (W_1 + W_2)⁻¹ (x_2 − x_1)``; side 1 moves by ``W_1 ν``, side 2
        by ``−W_2 ν``. For two point masses that is Eq. (30): both move to ``(m_1 x_1 + m_2 x_2) / (m_1 + m_2)``.
        """
        joint, subs = self.joint, self.subs
        d = joint.axes
        W = sum(outputs[joint.sides[side]][joint.inverse_mass[side]].reshape(d, d) for side in (0, 1))
        gaps = np.stack([y[1, 0] - y[0, 0], y[1, 1] - y[0, 1]])  # (position, velocity) × axes
        nu = np.linalg.solve(W, gaps.T).T
        sends = {subs[joint.sides[side]].name: encode(Kind.PROJECT, tick, tick * self.base, sign * nu.ravel())
                 for side, sign in ((0, 1.0), (1, -1.0))}
        replies = yield Exchange(sends, tuple(sends))
        return {joint.sides[side]: decode_output(replies[subs[joint.sides[side]].name], subs[joint.sides[side]], tick)
                for side in (0, 1)}


def implicit(plan: Plan, joint: JointPlan, settings: ImplicitSettings, pacer=None,
             progress: Callable[[int], None] | None = None, status: StatusReport | None = None,
             spill: Spill | None = None) -> Generator[Exchange, dict[str, bytes], RunRecord]:
    """Run the whole co-simulation; yields :class:`Exchange` requests, returns the :class:`RunRecord`.

    With ``status``, the SAVE that opens every macro-step after the first carries the status of the
    step before it (its step, as in jacobi), and a last exchange without commands the status of the last step.
    ``spill``: as in jacobi, where a long run's arrays go as it runs."""
    subs, n_ticks, k = plan.subsystems, plan.n_ticks, joint.k
    exchanges = _JointExchanges(plan, joint, settings, spill)
    history, side_outputs = exchanges.history, exchanges.side_outputs
    traj = [RowWindow(n_ticks + 1, len(s.outputs), float, np.nan, HISTORY_ROWS, spill, f"{s.name}-outputs")
            for s in subs]
    corrector_runs = RowWindow(n_ticks, None, np.int64, 0, 1, spill, "corrector-runs")
    releases = Releases(n_ticks, pacer, spill)
    for s, y in (yield from exchanges.consistent_start()).items():
        traj[s].array[0] = y

    diverged_at = None
    step_status = None
    for tick in range(n_ticks):
        yield from exchanges.control(Kind.SAVE, tick, subs, step_status)
        step_status = None  # reported
        released_ns = releases.release(tick)
        predicted = yield from exchanges.run(tick, subs, tick, 0)
        # e_N … e_{N-k}, a copy: the corrector's candidate may move the window (manager.scheme.window)
        newest_first = history.array[max(0, tick - k) - history.offset:tick + 1 - history.offset][::-1].copy()
        e_predicted = extrapolation_weights(len(newest_first) - 1) @ newest_first
        sensitivity = yield from exchanges.derivatives(predicted, e_predicted,
                                                       lambda e, targets: exchanges.corrector(tick, e, targets))
        y_predicted = side_outputs(predicted)
        if not (np.isfinite(y_predicted).all() and np.isfinite(sensitivity).all()):
            diverged_at = tick
            break

        e_new = corrected_coupling(joint.method, joint.decomposition, newest_first, y_predicted, sensitivity)
        corrected, e_new, runs = yield from exchanges.corrected(tick, e_new, sensitivity)
        corrector_runs.put(tick, runs)
        if joint.method.projects_states:
            corrected.update((yield from exchanges.project(side_outputs(corrected), corrected, tick + 1)))
        for s, y in corrected.items():
            traj[s].put(tick + 1, y)
        if status is not None:  # a rigid joint is no power bond: the status has timing only (logged: jacobi)
            status.log_times((tick + 1, released_ns, time.perf_counter_ns(),
                              0 if pacer is None else pacer.last_lateness_ns))
            step_status = tick + 1
        y_corrected = side_outputs(corrected)
        gap = np.max(np.abs(y_corrected[1, 0] - y_corrected[0, 0]))
        if not (gap <= settings.divergence_gap and np.isfinite(e_new).all()
                and all(np.isfinite(y).all() for y in corrected.values())):
            diverged_at = tick
            break
        if progress is not None and (tick + 1) % PROGRESS_EVERY == 0:
            progress(tick + 1)

    if step_status is not None:
        yield Exchange({}, (), step_status)
    done = n_ticks if diverged_at is None else diverged_at + 1  # macro-steps executed
    residual = np.broadcast_to(np.zeros(len(plan.bonds)), (n_ticks + 1, len(plan.bonds)))  # a joint is no power bond
    return RunRecord(plan, [window.finish() for window in traj], residual, residual, *releases.finish(done),
                     0 if pacer is None else pacer.missed,
                     implicit=ImplicitRecord(history.finish(), corrector_runs.finish(), diverged_at))
