"""References a run is compared with: the analytic solution and the monolithic run of a linear
point-mass scene, and for any scene the coupled equations integrated by scipy ``solve_ivp``.

The analytic and monolithic references are expressed through the monolithic model
(``manager.analysis.monolithic.build_monolithic``), whose outputs are every coupling signal and the energy; the
``solve_ivp`` reference resolves the couplings of the subsystems themselves. Either way a signal is
computed by the same output equations as in the co-simulation.
"""
from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from zencosim.compensation.analytic import free_response_blocks, linear_response_states
from zencosim.manager.analysis.monolithic import build_monolithic
from zencosim.manager.assembly import build_subsystems
from zencosim.manager.plan.run_plan import compile_plan
from zencosim.manager.scene.couplings import RigidJoint
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.window import BLOCK_ROWS, RowWindow, Spill
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.integrators.base import state_derivative

# LSODA switches between Adams (non-stiff) and BDF (stiff) by itself: the hydraulic crane is stiff (valve
# flow ~4000 1/s), DOP853 needs 114 s there and LSODA 3 s for the same result (docs/numerics.md, "References")
SOLVE_IVP_METHOD = "LSODA"
SOLVE_IVP_RTOL = 1e-10  # relative tolerance of the solve_ivp reference
SOLVE_IVP_ATOL = 1e-10  # absolute tolerance, in the units of each state (m, m/s, rad, rad/s, Pa)
# evaluations of the coupled equations the reference may take: a floor plus so many per macro-step (the bundled
# scenes take at most 5.6 per macro-step, nonlinear_oscillator_case1; a scene made absurdly stiff, e.g. a
# stiffness of 1e308 N/m, would keep LSODA going for hours)
SOLVE_IVP_EVALUATIONS = (100_000, 100)


class ReferenceFailed(RuntimeError):
    """A reference that could not be computed for this scene (the run itself is not affected)."""


@dataclass(frozen=True)
class Reference:
    """Signals and energy of a reference on the base macro-step grid (``n_ticks + 1`` samples); a long run's
    are spilled arrays (``manager.scheme.window``), read in blocks."""

    kind: str
    signals: dict[str, np.ndarray]
    energy: np.ndarray


class _ReferenceRows:
    """A reference's signals and energy, written tick by tick into windows of their newest values (the whole
    arrays in memory, or a long run's spilled as they are written)."""

    def __init__(self, n_ticks: int, names: list[str], spill: Spill | None) -> None:
        self.names = names
        self.windows = [RowWindow(n_ticks + 1, None, float, np.nan, 1, spill, f"reference-{name}")
                        for name in (*names, "energy")]

    def put(self, tick: int, values) -> None:
        """The signals' values at ``tick``, then the energy."""
        for window, value in zip(self.windows, values):
            window.put(tick, value)

    def put_rows(self, first: int, values: np.ndarray) -> None:
        """The signals' values (columns, energy last) at ticks ``first …``, a row per tick."""
        for window, column in zip(self.windows, values.T):
            window.put_rows(first, column)

    def finish(self, kind: str) -> Reference:
        arrays = [window.finish() for window in self.windows]
        return Reference(kind, dict(zip(self.names, arrays[:-1])), arrays[-1])


def _monolithic_rows(n_ticks: int, ports, spill: Spill | None) -> tuple[_ReferenceRows, list[int]]:
    """Rows for the monolithic model's outputs (energy last) and the output indices of its signals."""
    signals = [j for j, p in enumerate(ports) if p.quantity != "energy"]
    return _ReferenceRows(n_ticks, [ports[j].name for j in signals], spill), [*signals, -1]


def _put_free_response(rows: _ReferenceRows, columns: list[int], model, blocks: Iterator[np.ndarray],
                       step: float) -> None:
    """The outputs (``columns`` of them) of the monolithic ``model``, which has no inputs, at the states in
    ``blocks`` (rows of states at ticks 0, 1, … ``step`` [s] apart): their outputs in two matrix products a block
    (``MassesModel.outputs_of_rows``), so that a reference costs a few products per block, not a run."""
    first = 0
    for block in blocks:
        times = np.arange(first, first + len(block)) * step
        rows.put_rows(first, model.outputs_of_rows(times, block)[:, columns])
        first += len(block)


def _blocks(states: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
    """``states``, one at a time, as blocks of ``BLOCK_ROWS`` rows."""
    while block := list(itertools.islice(states, BLOCK_ROWS)):
        yield np.array(block)


def analytic_reference(scene: Scene, spill: Spill | None = None) -> Reference:
    """The exact solution of the monolithic linear system (matrix exponential, free and forced); ``spill``: where
    a long run's goes as it is computed (``manager.scheme.window``)."""
    mono = build_monolithic(scene)
    model = mono.model
    n = model.n_dof
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    Minv = np.linalg.inv(model.M)
    A[n:, :n] = -Minv @ model.K
    A[n:, n:] = -Minv @ model.C
    n_ticks = scene.manager.duration_ns // scene.manager.macro_step_ns
    step = scene.manager.macro_step_ns * 1e-9
    force = None
    B = None
    if model.external:
        B = np.zeros((2 * n, len(model.external)))
        for j, (_, body) in enumerate(model.external):
            B[n:, j] = Minv[:, body]
        force = lambda t: np.array([effect.force(t) for effect, _ in model.external])  # noqa: E731
    rows, columns = _monolithic_rows(n_ticks, model.outputs, spill)
    if force is None:  # z(k h) = e^{A k h} z0, a block at a time
        states = free_response_blocks(lambda m: expm(A * (m * step)), model.initial_state(), n_ticks, BLOCK_ROWS)
    else:
        states = _blocks(linear_response_states(A, model.initial_state(), step, n_ticks, B, force))
    _put_free_response(rows, columns, model, states, step)
    return rows.finish("analytic")


def monolithic_reference(scene: Scene, spill: Spill | None = None) -> Reference:
    """The monolithic system integrated with the subsystems' integrator (finest micro-step); ``spill`` as in
    ``analytic_reference``."""
    mono = build_monolithic(scene)
    base = scene.manager.macro_step_ns
    n_ticks = scene.manager.duration_ns // base
    no_inputs = InputPolynomial(np.empty((1, 0)))
    rows, columns = _monolithic_rows(n_ticks, mono.outputs, spill)
    step_matrix = mono.free_step(base)
    if step_matrix is not None:  # linear: the states of advance's step matrix, a block at a time
        blocks = free_response_blocks(lambda m: np.linalg.matrix_power(step_matrix, m), mono.z.copy(), n_ticks,
                                      BLOCK_ROWS)
        _put_free_response(rows, columns, mono.model, blocks, base * 1e-9)
        return rows.finish("monolithic")
    rows.put(0, np.asarray(mono.output_values(np.empty(0)), dtype=float)[columns])
    for k in range(n_ticks):
        rows.put(k + 1, np.asarray(mono.advance(k * base, (k + 1) * base, no_inputs), dtype=float)[columns])
    return rows.finish("monolithic")


class CoupledSystem:
    """Every subsystem of a scene as one ODE, the couplings resolved exactly at every evaluation.

    At time t the outputs are evaluated in the plan's initialisation order (subsystems without
    feedthrough first, then those whose feedthrough outputs need them), so every input is the exact
    current value of its source output: the continuous system the co-simulation approximates,
    without a hand-written monolithic model. A rigid joint is built force/force whatever its
    decomposition, and its force solves the joint on acceleration level (:class:`JointForce`).
    """

    def __init__(self, scene: Scene) -> None:
        scene = dataclasses.replace(scene, couplings={
            name: RigidJoint(name, dataclasses.replace(c.settings, decomposition="force-force"))
            if isinstance(c, RigidJoint) else c for name, c in scene.couplings.items()})
        subsystems = build_subsystems(scene)
        self.plan = compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})
        self.joints = [JointForce(c, self.plan) for c in scene.couplings.values() if isinstance(c, RigidJoint)]
        self.models = [subsystems[s.name].model for s in self.plan.subsystems]
        states = [m.initial_state() for m in self.models]
        bounds = np.cumsum([0] + [len(z) for z in states])
        self.slices = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
        self.z0 = np.concatenate(states)
        # per subsystem: its number of inputs, and per feed the source, the inputs it feeds and the outputs it takes
        self._feeds = [(len(s.inputs), [(f.source, np.array(f.inputs, dtype=np.intp),
                                         np.array(f.outputs, dtype=np.intp)) for f in s.feeds])
                       for s in self.plan.subsystems]

    def _inputs(self, i: int, outputs: list) -> np.ndarray:
        width, feeds = self._feeds[i]
        w = np.zeros(width)
        for source, inputs, taken in feeds:
            if outputs[source] is not None:
                w[inputs] = outputs[source][taken]
        return w

    def _resolved(self, t: float, Z: np.ndarray) -> tuple[list, list, list[np.ndarray]]:
        """At time t [s] and state ``Z``: each subsystem's outputs as the initialisation order last evaluated them, the
        inputs it evaluated them with (None for a subsystem it did not ask), and every subsystem's exact inputs."""
        outputs: list = [None] * len(self.models)
        asked: list = [None] * len(self.models)
        for round_ in self.plan.init_rounds:
            for step in round_:
                i = step.subsystem
                asked[i] = self._inputs(i, outputs)
                outputs[i] = self.models[i].outputs_at(t, Z[self.slices[i]], asked[i])
        inputs = [self._inputs(i, outputs) for i in range(len(self.models))]
        for joint in self.joints:
            joint.apply(outputs, inputs)
        return outputs, asked, inputs

    def resolve(self, t: float, Z: np.ndarray) -> list[np.ndarray]:
        """Every subsystem's input values at time t [s] and state ``Z``."""
        return self._resolved(t, Z)[2]

    def derivative(self, t: float, Z: np.ndarray) -> np.ndarray:
        inputs = self.resolve(t, Z)
        return np.concatenate([state_derivative(m, t, Z[sl], w) for m, sl, w in zip(self.models, self.slices, inputs)])

    def outputs(self, t: float, Z: np.ndarray) -> list[np.ndarray]:
        """Every subsystem's outputs (energy included) with the exact inputs: those the initialisation order
        evaluated with the same inputs, bit for bit, as they are (a model's outputs are a function of t, its state
        and its inputs); the others evaluated again."""
        outputs, asked, inputs = self._resolved(t, Z)
        return [y if w_asked is not None and w_asked.tobytes() == w.tobytes() else m.outputs_at(t, Z[sl], w)
                for m, sl, y, w_asked, w in zip(self.models, self.slices, outputs, asked, inputs)]


class JointForce:
    """The force of a rigid joint (built force/force) that holds it on acceleration level (paper 003
    Eq. 4, index 1). The sides' accelerations are affine in it, ``a_i(λ) = a_i(0) + s_i W_i λ`` with
    ``s = +1, −1`` and ``W_i`` the points' inverse effective masses, both reported by the models, so
    ``a_2(λ) = a_1(λ)`` gives ``λ = (W_1 + W_2)⁻¹ (a_2(0) − a_1(0))``. Position and velocity gaps then
    only drift by the integration error."""

    def __init__(self, joint: RigidJoint, plan) -> None:
        self.axes = joint.dimension
        self.sides = []
        for index in (0, 1):
            side, sub = joint.side(index), plan.by_name(joint.points[index][0])
            out = {p.name: j for j, p in enumerate(sub.outputs)}
            into = {p.name: j for j, p in enumerate(sub.inputs)}
            self.sides.append((sub.index, [out[n] for n in side.accelerations], [out[n] for n in side.inverse_masses],
                               [into[n] for n in side.inputs]))

    def apply(self, outputs: list[np.ndarray], inputs: list[np.ndarray]) -> None:
        """Set the joint force into ``inputs``; ``outputs`` were evaluated with the force zero."""
        (s1, a1, W1, _), (s2, a2, W2, _) = self.sides
        d = self.axes
        force = np.linalg.solve(outputs[s1][W1].reshape(d, d) + outputs[s2][W2].reshape(d, d),
                                outputs[s2][a2] - outputs[s1][a1])
        for sub, _, _, ports in self.sides:
            inputs[sub][ports] = force


def solve_ivp_reference(scene: Scene, rtol: float = SOLVE_IVP_RTOL, atol: float = SOLVE_IVP_ATOL,
                        spill: Spill | None = None) -> Reference:
    """The scene's coupled equations (:class:`CoupledSystem`) integrated in one pass by scipy's LSODA (tolerances
    ``rtol``, ``atol``), sampled on the base macro-step grid as ``solve_ivp`` samples its ``t_eval``: the ticks
    each solver step reaches, from that step's dense output, written as the step is taken. So a long run's
    reference (``spill``) goes to its files as it is computed, holding no more than a step's samples (at most
    ``BLOCK_ROWS`` at a time), and is the one a kept run's would be: integrating it block by block, restarting
    the integrator at each block, took five times the evaluations of the equations (hydraulic_crane_11_5ms:
    126,208 against 24,200)."""
    from scipy.integrate import LSODA  # here: scipy.integrate takes a second to load, which a run without this
    system = CoupledSystem(scene)      # reference (every subsystem process) need not pay
    base = scene.manager.macro_step_ns
    n_ticks = scene.manager.duration_ns // base
    step = base * 1e-9
    names = list(system.plan.signals)
    rows = _ReferenceRows(n_ticks, names, spill)
    budget = SOLVE_IVP_EVALUATIONS[0] + SOLVE_IVP_EVALUATIONS[1] * n_ticks
    evaluations = itertools.count(1)

    def derivative(tk: float, Z: np.ndarray) -> np.ndarray:
        if next(evaluations) > budget:
            raise ReferenceFailed(f"the solve_ivp reference took more than {budget:,} evaluations of the coupled "
                                  f"equations ({SOLVE_IVP_METHOD}, rtol {rtol:g}, atol {atol:g}): the scene is too "
                                  "stiff")
        try:
            return system.derivative(tk, Z)
        except ArithmeticError as error:  # a trial state of LSODA beyond what a model's maths holds
            raise ReferenceFailed(f"the solve_ivp reference failed at t = {tk:g} s: {error}") from None

    reporting = [s for s in system.plan.subsystems if s.energy_output is not None]
    # the first step is the base macro-step: scipy's own guess assumes smoothness that a system starting at rest
    # (derivative 0 at t = 0) does not show, and its trial states may overflow
    solver = LSODA(derivative, 0.0, system.z0, n_ticks * step, rtol=rtol, atol=atol, first_step=step)
    tick = 0  # the next tick to sample
    while tick <= n_ticks:
        if solver.status == "finished":
            raise ReferenceFailed(f"the solve_ivp reference ended at t = {solver.t:g} s, before t = {tick * step:g} s")
        message = solver.step()
        if solver.status == "failed":
            raise ReferenceFailed(f"the solve_ivp reference failed ({SOLVE_IVP_METHOD}: {message})")
        reached = _ticks_reached(solver.t, step, n_ticks)
        if reached > tick:
            dense = solver.dense_output()
            for first in range(tick, reached, BLOCK_ROWS):
                t = np.arange(first, min(first + BLOCK_ROWS, reached)) * step
                states = dense(t)
                for k in range(len(t)):
                    y = system.outputs(t[k], states[:, k])
                    rows.put(first + k, [*(y[sub][j] for sub, j in system.plan.signals.values()),
                                         sum(y[s.index][s.energy_output] for s in reporting)])
            tick = reached
    return rows.finish("solve_ivp")


def _ticks_reached(t: float, step: float, n_ticks: int) -> int:
    """How many ticks ``0 … n_ticks`` lie at or before ``t`` [s], a tick ``k`` at ``k × step`` as ``np.arange(n_ticks
    + 1) * step`` has it (``np.searchsorted(…, t, "right")``, without the array)."""
    k = min(int(t / step), n_ticks)
    while k < n_ticks and (k + 1) * step <= t:
        k += 1
    while k > 0 and k * step > t:
        k -= 1
    return k + 1
