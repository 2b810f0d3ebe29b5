"""The energy corrector: paper 002 Eqs. 13–17 applied by the manager to the receiving subsystems.

Bonds whose motion sides are one point of one subsystem (the multiple oscillator's star, paper 002
Fig. 14) form one *group* with a single correction force, as in the paper: the group's energy error
is ``ζ = Σ_b μ_b δE_b`` over its last macro-step (each bond's residual is taken first, then weighted),
its uncorrected coupling force is the sum of the bonds' forces, and its velocity is the point's.
The macro-step H of a group is the interval between the points where all its sides communicate.

Sign: a bond's force signal is the force on the receiving point, which the motion side applies as it
receives it (``subsystems.ports``). The paper's ``f`` (the force on the receiving subsystem) is
therefore ``Σ fc``, and its ``f_corr`` (``compensation.energy_correction``) is applied by sending
``fc* + f_corr`` on the group's first force input. Logged forces are the paper's ``f_corr``: the force
the correction exerts on the receiving point.

The correction is added to the constant coefficient of the input polynomial of every step of the
receiving subsystem that starts in [t_{k+1}, t_{k+2}); the residual power is still evaluated with the
polynomial the extrapolation produced (see manager.scheme.residual).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from zencosim.compensation.energy_correction import EnergyCorrection, correction_coefficient
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scene.settings import CorrectionSettings
from zencosim.manager.scheme.window import RowWindow, Spill


@dataclass
class CorrectionLog:
    """What the corrector did to one receiving point."""

    name: str  # the group: its bonds joined by '+'
    subsystem: str  # the receiving (motion-side) subsystem
    bonds: tuple[str, ...]
    mu: tuple[float, ...]  # μ of each bond
    force: np.ndarray  # (n_ticks, dimension) [N] f_corr on the receiving point over [t_j, t_j+1]
    uncorrected_energy: np.ndarray  # (n_ticks + 1,) [J] 𝒰 at the group's correction points, NaN elsewhere
    work: np.ndarray  # (n_ticks + 1,) [J] cumulative work of f_corr on the receiving point, NaN between its points
    capped_steps: int  # corrections a cap limited
    withheld_steps: int  # corrections withheld: the flow left rest (compensation.energy_correction)
    steps: int  # corrections computed
    energy_error: float  # [J] Σ ζ: the energy error the correction was meant to cancel (Eq. 13, summed)


def bond_mu(plan: Plan, bond_index: int, settings: CorrectionSettings) -> float:
    """μ of a bond: the scene's number, or the rules of paper 002 §3.3 ("auto")."""
    if settings.mu != "auto":
        return settings.mu
    bond = plan.bonds[bond_index]
    force_side, motion_side = plan.subsystems[bond.force_side], plan.subsystems[bond.motion_side]
    feedthrough = any(force_side.outputs[i].feedthrough for i in bond.force_output)
    faster = force_side if force_side.ratio < motion_side.ratio else motion_side
    return correction_coefficient(feedthrough, Fraction(force_side.ratio), Fraction(motion_side.ratio), faster.order)


class _Group:
    """One receiving point and the bonds that act on it."""

    def __init__(self, plan: Plan, bonds: list[int], settings: CorrectionSettings, spill: Spill | None) -> None:
        first = plan.bonds[bonds[0]]
        self.bonds = tuple(bonds)
        self.name = "+".join(plan.bonds[b].name for b in bonds)
        self.motion = first.motion_side
        self.motion_ratio = plan.subsystems[self.motion].ratio
        self.velocity = list(first.velocity_output)
        self.force_input = list(first.force_input)
        self.forces = [(plan.bonds[b].force_side, plan.subsystems[plan.bonds[b].force_side].ratio,
                        list(plan.bonds[b].force_output)) for b in bonds]
        self.interval = math.lcm(self.motion_ratio, *(ratio for _, ratio, _ in self.forces))
        self.macro_step = self.interval * plan.base_step_ns * 1e-9  # H [s]
        self.motion_step = self.motion_ratio * plan.base_step_ns * 1e-9  # the receiving subsystem's step [s]
        self.mu = tuple(bond_mu(plan, b, settings) for b in bonds)
        dimension = len(self.velocity)
        self.law = EnergyCorrection(settings.nu, settings.cap_fraction, settings.cap_force, dimension)
        self.subsystem = plan.subsystems[self.motion].name
        self.bond_names = tuple(plan.bonds[b].name for b in bonds)
        n = plan.n_ticks
        history = 2 * self.interval + self.motion_ratio  # rows read back (manager.scheme.window): the last step's force
        self.force = RowWindow(n, dimension, float, 0.0, history, spill, f"{self.name}-correction-force")
        self.uncorrected_energy = RowWindow(n + 1, None, float, np.nan, 1, spill, f"{self.name}-uncorrected-energy")
        self.work_done = RowWindow(n + 1, None, float, np.nan, 1, spill, f"{self.name}-correction-work")
        self.uncorrected_energy.array[0] = 0.0
        self.work_done.array[0] = 0.0
        self.capped_steps = 0
        self.withheld_steps = 0
        self.steps = 0
        self.energy_error = 0.0
        self.last_tick = 0
        self.work = 0.0

    def log(self) -> CorrectionLog:
        return CorrectionLog(self.name, self.subsystem, self.bond_names, self.mu, self.force.finish(),
                             self.uncorrected_energy.finish(), self.work_done.finish(), self.capped_steps,
                             self.withheld_steps, self.steps, self.energy_error)


class EnergyCorrector:
    """The :class:`manager.scheme.base.Corrector` of paper 002 §3.2, for every power bond of a plan."""

    def __init__(self, plan: Plan, settings: CorrectionSettings, local: frozenset[int] | None = None,
                 spill: Spill | None = None) -> None:
        """Every receiving point's group, or those of the ``local`` subsystems (a subsystem process corrects
        its own inputs only); ``spill``: where a long run's logs go (``manager.scheme.window``)."""
        members: dict[tuple, list[int]] = {}
        for b, bond in enumerate(plan.bonds):
            if local is None or bond.motion_side in local:
                members.setdefault((bond.motion_side, bond.velocity_output), []).append(b)
        self.groups = [_Group(plan, bonds, settings, spill) for bonds in members.values()]
        self.targets = frozenset(g.motion for g in self.groups)
        self._by_target = {sub: [g for g in self.groups if g.motion == sub] for sub in self.targets}

    def adjust(self, sub: int, tick: int, coefficients: np.ndarray) -> np.ndarray:
        corrected = coefficients.copy()
        for group in self._by_target[sub]:
            corrected[0, group.force_input] += group.law.force
        return corrected

    def observe(self, tick: int, trajectories: list[RowWindow], residual_energy: RowWindow) -> None:
        for group in self.groups:
            ratio = group.motion_ratio
            for window, last in ((group.force, min(tick + group.interval, group.force.rows) - 1),  # set ahead
                                 (group.uncorrected_energy, tick), (group.work_done, tick)):
                if last >= window.end:
                    window.advance(last)
            path = trajectories[group.motion]
            if group.law.previous_velocity is None:  # the flow at t_0, from which the first correction's is judged
                group.law.previous_velocity = path.row(0)[group.velocity].astype(np.float64)
            if tick % ratio == 0:  # work of the correction over the receiving subsystem's last step (trapezoid)
                v0, v1 = path.row(tick // ratio - 1)[group.velocity], path.row(tick // ratio)[group.velocity]
                group.work += float(group.force.row(tick - ratio).dot(v0 + v1)) * 0.5 * group.motion_step
                group.work_done.array[tick - group.work_done.offset] = group.work
            if tick % group.interval:
                continue
            zeta = sum(mu * (residual_energy.row(tick)[b] - residual_energy.row(group.last_tick)[b])
                       for mu, b in zip(group.mu, group.bonds))
            velocity = trajectories[group.motion].row(tick // ratio)[group.velocity]
            coupling_force = sum(trajectories[side].row(tick // side_ratio)[outputs]
                                 for side, side_ratio, outputs in group.forces)
            force = group.law.update(float(zeta), velocity, coupling_force, group.macro_step)
            start = tick - group.force.offset
            group.force.array[start:start + group.interval] = force
            group.uncorrected_energy.array[tick - group.uncorrected_energy.offset] = group.law.uncorrected
            group.capped_steps += group.law.capped
            group.withheld_steps += group.law.withheld
            group.energy_error += float(zeta)
            group.steps += 1
            group.last_tick = tick

    def log(self) -> tuple[CorrectionLog, ...]:
        """One log per receiving point (once, when the run has ended)."""
        return tuple(g.log() for g in self.groups)


def build_correctors(plan: Plan, settings: CorrectionSettings | None, local: frozenset[int] | None = None,
                     spill: Spill | None = None) -> tuple:
    """The correctors a scene asks for (none when it asks for none), for the ``local`` subsystems' inputs
    (None: every subsystem's); ``spill`` as in ``manager.scheme.jacobi``."""
    if settings is None or not settings.enabled:
        return ()
    return (EnergyCorrector(plan, settings, local, spill),)
