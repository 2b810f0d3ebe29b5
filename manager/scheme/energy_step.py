"""The energy-controlled macro-step: Jacobi steps whose length a PI law sets from the bonds' residual energy.

This is the ECCO method (S. Sadjina, E. Pedersen, "Energy conservation and coupling error reduction in
non-iterative co-simulations", Engineering with Computers 36, 2020) as libcosim's ``ecco_algorithm`` implements
it (libcosim 0.11, ``adjust_step_size``), with its parameters under its names ([manager.energy_control],
``EnergyControlSettings``). Like ``manager.scheme.jacobi`` the scheme is a generator of :class:`Exchange`
requests, so both buses run the same arithmetic; every process of a run over Zenoh follows every subsystem
(the step length depends on every bond), as the implicit scheme's do.

One macro-step [t_k, t_k + H_k]: every subsystem gets, per input, the Lagrange polynomial of its order through
its source's newest points at their times (paper 002 Fig. 5 at varying spacing; zero-order: the outputs at t_k,
as libcosim holds them), steps by H_k (the STEP command's length, ``manager.wire.protocol``), and the manager
evaluates the residual power δP_b of every bond at t_k + H_k (``manager.scheme.residual``, paper 002 Eq. 9: for
zero-order inputs |δP_b| = |P_a − P_b|, the difference of the powers input × output of libcosim's two sides) and
its residual energy ΔE_b = δP_b H_k. At a constant step this is ``manager.scheme.jacobi``'s step, bit for bit. After every step from the second on (libcosim's, as it does):

    ε = sqrt( (1/B) Σ_b ( |δP_b| H / (abs_tolerance + rel_tolerance · max_b |δP_b| H) )² )
    ε = 0 or ε_prev = 0:  H unchanged, ε_prev ← ε          (ε_prev starts at 1)
    else:                 g = clamp(safety_factor · ε^(−i_gain − p_gain) · ε_prev^(p_gain), min_change_rate,
                                    max_change_rate),  ε_prev ← ε,
                          H ← clamp(g H, min_step_size, max_step_size)

``rel_tolerance`` multiplies the largest residual energy of the step, not the energy a bond exchanged: that is
libcosim's law, kept so that a system imported from OSP steps as it does there. H is counted in whole
nanoseconds, g H truncated to them, as libcosim does; the macro-step taken is H truncated to a whole multiple of
``manager.macro_step`` (the subsystems' micro-steps divide it), and the residual energy is that of the step taken:
with a macro-step of 1 ns, libcosim's arithmetic. The last step is cut to end at the duration.

Multi-rate: the law sets the length of the schedule's period (the lcm of the ratios) once per period, from the
residuals at its end, where every bond is evaluated; the period's points are evenly spaced and each subsystem steps
``ratio`` of them at a time, as in ``manager.scheme.jacobi`` (whose run it is, bit for bit, at a constant step).
``min_step_size``, ``step_size`` and ``max_step_size`` bound the points' spacing.

Defaults drawn from the scene (:func:`step_bounds`, :func:`abs_tolerance`): the macro-step is the smallest and the
first step, ``DEFAULT_MAX_STEPS`` of the smallest the largest, and ``abs_tolerance`` is ``DEFAULT_ENERGY_FRACTION`` of
the energy the subsystems report at t_0 (libcosimpy's 1e-4 J where they report none).

The record holds one row per point (``RunRecord.point_ticks``: the base step of each; a subsystem's trajectory, one
per ``ratio`` points).
"""
from __future__ import annotations

import math
import time
from typing import Callable, Generator

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scene.settings import EnergyControlSettings
from zencosim.manager.scheme.base import (
    HISTORY_ROWS,
    PROGRESS_EVERY,
    Exchange,
    OutputReader,
    RunRecord,
    SubsystemCalls,
)
from zencosim.manager.scheme.extrapolation import sample_matrix
from zencosim.manager.scheme.jacobi import bond_residual_power, gathered_inputs, initial_outputs, schedule
from zencosim.manager.scheme.pacing import Releases
from zencosim.manager.scheme.window import RowWindow, Spill
from zencosim.manager.wire.protocol import Kind, encode
from zencosim.manager.wire.status import StatusReport


DEFAULT_MAX_STEPS = 20  # max_step_size when the scene gives none: this many of the smallest step
DEFAULT_ENERGY_FRACTION = 1e-3  # abs_tolerance when the scene gives none: this fraction of its energy at t_0, per step
FALLBACK_ABS_TOLERANCE = 1e-4  # [J] abs_tolerance of a scene that reports no energy at t_0 (libcosimpy's)


def step_bounds(control: EnergyControlSettings, macro_step_ns: int) -> tuple[int, int, int]:
    """``(min_step_size, step_size, max_step_size)`` [ns] of ``control``, the scene's defaults in place of those it
    leaves out: the macro-step ``macro_step_ns`` as the smallest step, the smallest as the first, and
    ``DEFAULT_MAX_STEPS`` smallest steps (at least the first) as the largest."""
    low = macro_step_ns if control.min_step_size is None else round(control.min_step_size * 1e9)
    first = low if control.step_size is None else round(control.step_size * 1e9)
    high = max(DEFAULT_MAX_STEPS * low, first) if control.max_step_size is None else round(control.max_step_size * 1e9)
    return low, first, high


def abs_tolerance(control: EnergyControlSettings, initial_energy: float | None) -> float:
    """``abs_tolerance`` [J] of ``control``: the scene's, else ``DEFAULT_ENERGY_FRACTION`` of ``initial_energy``
    [J] (the total the subsystems report at t_0; None: none reports one), else ``FALLBACK_ABS_TOLERANCE``."""
    if control.abs_tolerance is not None:
        return control.abs_tolerance
    if initial_energy is not None and math.isfinite(initial_energy) and abs(initial_energy) > 0.0:
        return DEFAULT_ENERGY_FRACTION * abs(initial_energy)
    return FALLBACK_ABS_TOLERANCE


def initial_energy(plan: Plan, first_rows: list[np.ndarray]) -> float | None:
    """The subsystems' total energy [J] at t_0 from each one's first row of outputs ``first_rows`` (None: no
    subsystem reports its energy); summed in subsystem order, as the run summary sums it."""
    reporting = [s for s in plan.subsystems if s.energy_output is not None]
    return sum(float(first_rows[s.index][s.energy_output]) for s in reporting) if reporting else None


class StepLaw:
    """The PI law of the module text: the step it sets, ``step_ns`` (libcosim's, whole nanoseconds), and the
    macro-step taken, ``ticks`` (that step truncated to whole base steps of ``base_step_ns``: the law itself goes on
    from the step it set, so that a rate below 2 can lengthen a step of one base step). Its ``abs_tolerance`` is the
    scene's, or is set from the run's energy at t_0 (:meth:`scale_to`) before the first step."""

    def __init__(self, control: EnergyControlSettings, base_step_ns: int, period: int = 1) -> None:
        self.control = control
        self.base_step_ns = base_step_ns
        self.period = period
        low, first, high = step_bounds(control, base_step_ns)
        self.min_ns, self.step_ns, self.max_ns = period * low, period * first, period * high
        self.abs_tolerance = abs_tolerance(control, None)
        self.previous_error = 1.0

    def scale_to(self, energy: float | None) -> None:
        """Take the tolerance relative to the run's total energy at t_0, ``energy`` [J] (``abs_tolerance``)."""
        self.abs_tolerance = abs_tolerance(self.control, energy)

    def most_points(self, n_ticks: int) -> int:
        """The most points a run of ``n_ticks`` base steps can have: every period the shortest, the last one cut,
        and t_0."""
        return n_ticks // (self.min_ns // (self.base_step_ns * self.period)) + self.period + 1

    @property
    def ticks(self) -> int:
        """The next period [base steps]: a whole number of the period's points."""
        return self.step_ns // (self.base_step_ns * self.period) * self.period

    def adjust(self, residual_power: list[float], start_ns: int, taken_ns: int) -> None:
        """Set the next step after one of ``taken_ns`` from ``start_ns`` whose bonds had ``residual_power`` [W] at
        its end."""
        c = self.control
        dt = (start_ns + taken_ns) / 1e9 - start_ns / 1e9  # libcosim's to_double_duration(step, start)
        magnitudes = [abs(p) for p in residual_power]
        energy_level = max(magnitudes) * dt
        mean_square = 0.0
        for magnitude in magnitudes:
            ratio = magnitude * dt / (self.abs_tolerance + c.rel_tolerance * energy_level)
            mean_square += ratio * ratio
        error = math.sqrt(mean_square / len(magnitudes))
        diverged = not (math.isfinite(error) and math.isfinite(self.previous_error))  # its summary says so
        if error == 0 or self.previous_error == 0 or diverged:
            self.previous_error = error  # the step stays
            return
        gain = c.safety_factor * error ** (-c.i_gain - c.p_gain) * self.previous_error ** c.p_gain
        gain = min(max(gain, c.min_change_rate), c.max_change_rate)
        self.previous_error = error
        step = (start_ns + self.step_ns) / 1e9 - start_ns / 1e9
        self.step_ns = min(max(int(gain * step * 1e9), self.min_ns), self.max_ns)  # to_duration truncates to ns


def energy_controlled(plan: Plan, law: StepLaw, progress: Callable[[int], None] | None = None,
                      status: StatusReport | None = None, spill: Spill | None = None,
                      direct: SubsystemCalls | None = None) -> Generator[Exchange, dict[str, bytes], RunRecord]:
    """Run the whole co-simulation at the macro-steps ``law`` sets (a fresh one); yields :class:`Exchange` requests,
    returns the :class:`RunRecord` (a row per communication point). ``progress`` is called with the base step reached about
    every ``PROGRESS_EVERY`` macro-steps; ``status`` and ``spill`` as in ``manager.scheme.jacobi``; ``direct``: the
    subsystems of an unrecorded in-process run, which the scheme then calls itself with the values the commands
    would carry (``manager.bus.inproc.DirectCalls``), yielding nothing."""
    subs, base, end = plan.subsystems, plan.base_step_ns, plan.n_ticks
    period = law.period
    points = law.most_points(end)
    readers = [OutputReader(s, (points - 1) // s.ratio + 1, spill) for s in subs]
    n_bonds = len(plan.bonds)
    p_window = RowWindow(points, n_bonds, float, np.nan, HISTORY_ROWS + period, spill, "residual-power")
    e_window = RowWindow(points, n_bonds, float, np.nan, HISTORY_ROWS + period, spill, "residual-energy")
    ticks = RowWindow(points, None, np.int64, 0, HISTORY_ROWS * period, spill, "point-ticks")
    p_window.array[0], e_window.array[0], ticks.array[0] = 0.0, 0.0, 0
    releases = Releases(points - 1, None, spill)
    energy = [0.0] * n_bonds
    last_bond_point = [0] * n_bonds
    everyone = frozenset(range(len(subs)))
    sources = [tuple((readers[f.source], subs[f.source].ratio, list(f.outputs), list(f.inputs), f.order)
                     for f in s.feeds) for s in subs]
    # zero-order inputs each fed once: per input, where its value lies in its source's newest outputs
    held = [gathered_inputs(s, readers) for s in subs]
    # per phase of the Jacobi schedule (one stage): who starts a step, whose replies are due at its end and their
    # names, the bonds evaluated there (both sides communicate)
    phases = [(starting, due, due_names, evaluated)
              for ((starting, _, due, due_names, _),), evaluated in schedule(plan, everyone, everyone)[1]]
    sent: list[tuple[int, list] | None] = [None] * len(subs)  # per subsystem: (start tick, polynomial rows)
    computed: list = [None] * len(subs)  # direct: the outputs each subsystem's step computed

    def input_polynomial(s: SubsystemPlan, tick: int = 0, stepping: bool = True) -> np.ndarray:
        """``s``'s input polynomial over its step from ``tick`` (base point ``point``): per feed, the Lagrange
        polynomial of its order through its source's newest samples at or before it, at their times (fewer at the
        start of the run); at t_0 (``stepping`` False, as ``initial_outputs`` asks) the sources' first rows."""
        coefficients = np.zeros((s.order + 1, len(s.inputs)))
        for reader, ratio, outputs, inputs, order in sources[s.index]:
            window = reader.window
            if not stepping:
                coefficients[0, inputs] = window.array[0, outputs]
                continue
            newest = point // ratio
            samples = min(order, newest) + 1
            first = newest - samples + 1
            rows = window.array[first - window.offset:newest + 1 - window.offset, outputs]
            if samples == 1:
                coefficients[0, inputs] = rows[0]
                continue
            offsets = tuple((int(ticks.row(j * ratio)) - tick) * base for j in range(first, newest + 1))
            coefficients[:samples, inputs] = sample_matrix(offsets).dot(rows)
        return coefficients

    point = 0
    yield from initial_outputs(plan, readers, input_polynomial, everyone, everyone, direct, None)
    law.scale_to(initial_energy(plan, [reader.window.row(0) for reader in readers]))

    tick, step_status, periods = 0, None, 0
    step_s = base * 1e-9
    while tick < end:
        length = min(law.ticks, end - tick)  # the period's base steps: a whole number of its points'
        spacing = length // period  # base steps between two points of this period
        spacing_s = spacing * base * 1e-9  # as the Jacobi scheme's step: one at a fixed step (tests/manager/test_energy_step)
        period_start_ns = tick * base
        for starting, due, due_names, evaluated in phases:
            # every polynomial from the outputs at or before the step's start (Jacobi); a zero-order one as its
            # values, the sources' newest floats
            for s in starting:
                sent[s.index] = (tick, [[reader.newest[output] for reader, output in held[s.index]]]
                                 if held[s.index] is not None else input_polynomial(s, tick).tolist())
            released_ns = releases.release(point)
            due_tick = tick + spacing
            point += 1
            if direct is None:
                replies = yield Exchange({s.name: encode(Kind.STEP, tick, tick * base, np.array(sent[s.index][1]),
                                                         s.order + 1, ref=s.ratio * spacing) for s in starting},
                                         due_names, step_status, due_tick)
                for s in due:
                    readers[s.index].commit(replies[s.name], due_tick, point // s.ratio)
            else:  # the values a STEP would carry: a zero-order one's as floats, as the endpoint takes them
                for s in starting:
                    rows = sent[s.index][1]
                    computed[s.index] = direct.step(s, tick, rows[0] if s.order == 0 else np.array(rows),
                                                    s.ratio * spacing)
                for s in due:
                    readers[s.index].commit_values(computed[s.index], due_tick, point // s.ratio)
            ticks.put(point, due_tick)
            residual_power, residual_energy = [math.nan] * n_bonds, [math.nan] * n_bonds
            for b, bond, components in evaluated:
                delta_p = bond_residual_power(readers, sent, bond, components, due_tick, step_s)
                energy[b] += delta_p * (point - last_bond_point[b]) * spacing_s
                last_bond_point[b] = point
                residual_power[b], residual_energy[b] = delta_p, energy[b]
            p_window.put(point, residual_power)
            e_window.put(point, residual_energy)
            if status is not None:
                status.log_residuals(residual_power + residual_energy)
                status.log_times((due_tick, released_ns, time.perf_counter_ns(), 0))
                step_status = due_tick
            tick = due_tick
            if progress is not None and point % PROGRESS_EVERY == 0:
                progress(tick)
        periods += 1
        if periods >= 2:  # at the period's end every bond was evaluated
            law.adjust(residual_power, period_start_ns, length * base)
    if step_status is not None:
        yield Exchange({}, (), step_status)
    rows = point + 1
    return RunRecord(plan, [reader.window.finish((rows - 1) // s.ratio + 1) for s, reader in zip(subs, readers)],
                     p_window.finish(rows), e_window.finish(rows), *releases.finish(point), 0,
                     point_ticks=ticks.finish(rows))
