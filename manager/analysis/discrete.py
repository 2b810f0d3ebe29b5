"""Exact discrete analysis of the explicit Jacobi scheme for a linear scene (issue 5, item 4).

The scheme of ``manager.scheme.jacobi`` applied to linear subsystems is a linear map. Over one period of
its schedule (``lcm`` of the communication ratios base steps; one macro-step when single-rate)
it advances the discrete state

    X = [z_1, ..., z_S, Y_1[k-p..k], ..., Y_S[k-p..k]]

— every subsystem's state ``z = [x, v]`` at its communication point and the last ``p + 1``
committed samples of its linear outputs (``p`` the highest extrapolation order of the receivers)
— by ``X⁺ = Ψ X``.
``Ψ`` is built by running the scheme symbolically: every quantity is a matrix acting on ``X``,
and each step follows ``manager.scheme.jacobi`` exactly:

1. the input polynomial of a subsystem starting a step is the Lagrange extrapolation of its own
   order (``manager.scheme.extrapolation.extrapolation_matrix``, the same cached matrices) of the newest
   committed samples of its sources, with the multi-rate offset of a slow source;
2. over its communication step the subsystem applies its integrator's one-step map
   (``linear_step`` of ``subsystems.integrators``) with its micro-step, the input polynomial
   evaluated at the integrator's nodes (``z_end = Φ_S z + Σ_q Γ_{S,q} c_q``, ``c_q`` the
   coefficients of ``τ^q``);
3. its outputs at the new point use the polynomial evaluated there (direct feedthrough,
   docs/numerics.md) and are committed when simulated time reaches that point.

Eigenvalues ``μ`` of ``Ψ`` map to continuous poles by ``s = ln(μ) / T`` (``T`` the period); the
spectral radius ``ρ(Ψ)`` decides stability. Zero eigenvalues belong to redundant states (a
committed motion output equals a component of ``z``) and have no pole. Limits: the steady-state
map (the first ``p`` steps of a run use fewer samples); external forces of time are a forcing
term, not part of ``Ψ``; ``masses`` models whose public matrices are their whole dynamics
(not ``MassesModel.nonlinear``) enter exactly, FMUs and Python models by their identified one-step maps
(``manager.analysis.identified``, through ``scene_scheme``); no energy correction (``manager.correction``: its
capped correction is not linear); ``LinearSceneError`` otherwise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from zencosim.manager.analysis.identified import (
    Identification,
    IdentificationError,
    IdentifiedStep,
    identified_steps,
)
from zencosim.manager.analysis.monolithic import discrete_unavailable
from zencosim.manager.plan.attachments import build_subsystem, coupling_attachments
from zencosim.manager.plan.run_plan import Plan, compile_plan
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.extrapolation import extrapolation_matrix
from zencosim.subsystems.integrators.base import composed_linear_step
from zencosim.subsystems.models.external.fmu import FmuError
from zencosim.subsystems.models.external.model import ExternalModel
from zencosim.subsystems.models.masses import MassesModel
from zencosim.subsystems.subsystem import Subsystem

ZERO_EIGENVALUE = 1e-10  # |μ| below which an eigenvalue belongs to a redundant state (no pole)
MARGINAL = 1e-9  # ρ <= 1 + MARGINAL is stable: round-off of a marginally stable (symplectic) spectrum


class LinearSceneError(ValueError):
    """The scene is not linear, so the discrete scheme has no transition matrix."""


@dataclass(frozen=True)
class SubsystemMap:
    """One communication step of one subsystem: ``z_end = Φ z + Σ_q Γ[q] c_q``, ``y = C_y z_end + D_y w(H)``."""

    Phi: np.ndarray  # (2n, 2n)
    Gamma: np.ndarray  # (p + 1, 2n, n_inputs): response to the coefficient of tau^q
    C_y: np.ndarray
    D_y: np.ndarray
    span: float  # communication step H [s]


def subsystem_map(sub: Subsystem, span_ns: int, order: int) -> SubsystemMap:
    """Compose the integrator's one-step map over the ``span_ns / micro_step`` micro-steps of a step."""
    model = sub.model
    if not isinstance(model, MassesModel) or model.nonlinear:
        raise LinearSceneError(f"subsystem {sub.name}: the discrete analysis needs linear '{MassesModel.name}' "
                               f"models, got {type(model).__name__} with effects {', '.join(model.effects)}")
    Phi, Gamma = composed_linear_step(type(sub.integrator), model.A_a, model.B_a, sub.micro_step_ns * 1e-9,
                                      span_ns // sub.micro_step_ns, order + 1)
    return SubsystemMap(Phi, Gamma.transpose(1, 0, 2), model.C_y, model.D_y, span_ns * 1e-9)


def identified_map(step: IdentifiedStep, span_ns: int) -> SubsystemMap:
    """The one-step map of an identified subsystem (its state ``ξ = [s; y]``, ``manager.analysis.identified``)."""
    return SubsystemMap(step.Phi, step.Gamma, step.C_y, step.D_y, span_ns * 1e-9)


@dataclass(frozen=True)
class DiscreteScheme:
    """``X⁺ = Ψ X`` over one period of the schedule, and the layout of ``X``."""

    Psi: np.ndarray
    period: float  # [s]
    z_index: tuple[slice, ...]  # per subsystem (plan order): its state z = [x, v]
    history_index: tuple[tuple[slice, ...], ...]  # per subsystem: its output samples, oldest first
    identifications: tuple[Identification, ...] = ()  # how each identified subsystem was (plan order)

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.Psi)

    @property
    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.eigenvalues())))

    @property
    def stable(self) -> bool:
        """``ρ(Ψ) <= 1`` up to round-off (``MARGINAL``)."""
        return self.spectral_radius <= 1.0 + MARGINAL

    @property
    def growth_rate(self) -> float:
        """Exponential growth rate [1/s] of the energy of the least damped mode: ``2 ln ρ / T`` (−∞ for ``ρ = 0``: no
        loop, every identified subsystem a source or a sink)."""
        radius = self.spectral_radius
        return 2.0 * math.log(radius) / self.period if radius > 0.0 else -math.inf

    def poles(self) -> np.ndarray:
        """``ln(μ) / T`` [1/s] of every non-zero eigenvalue (principal branch: ``|Im s| <= π / T``)."""
        mu = self.eigenvalues()
        return np.log(mu[np.abs(mu) > ZERO_EIGENVALUE].astype(complex)) / self.period

    def primary_poles(self, monolithic: np.ndarray) -> np.ndarray:
        """The poles paired one-to-one with ``monolithic`` (same order) at least total distance."""
        return self.primary_eigenstructure(monolithic)[0]

    def primary_eigenstructure(self, monolithic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``primary_poles`` and their mode shapes: the body positions of each eigenvector of ``Ψ``
        (subsystems in plan order, ``z = [x, v]``), unit norm, largest entry real and positive."""
        # imported here: scipy.optimize takes a third of a second to import, which a run's summary need not pay
        from scipy.optimize import linear_sum_assignment

        from zencosim.compensation.eigenstructure.modes import normalize_mode_shape
        mu, V = np.linalg.eig(self.Psi)
        live = np.abs(mu) > ZERO_EIGENVALUE
        poles, V = np.log(mu[live].astype(complex)) / self.period, V[:, live]
        _, pick = linear_sum_assignment(np.abs(monolithic[:, None] - poles[None, :]))
        positions = np.concatenate([np.arange(z.start, (z.start + z.stop) // 2) for z in self.z_index])
        shapes = np.column_stack([normalize_mode_shape(V[positions, k]) for k in pick])
        return poles[pick], shapes


def discrete_scheme(plan: Plan, subsystems: dict[str, Subsystem],
                    identified: dict[str, IdentifiedStep] | None = None) -> DiscreteScheme:
    """``Ψ`` of the explicit scheme (``manager.scheme.jacobi``: Jacobi, or Gauss–Seidel stage after stage as
    ``plan.stages`` orders them) for ``plan`` and its built subsystems, those in ``identified`` by their identified
    one-step maps (``manager.analysis.identified``)."""
    subs = plan.subsystems
    depth = max(s.order for s in subs)  # history kept: depth + 1 samples of every subsystem
    base = plan.base_step_ns
    identified = identified or {}
    maps = [identified_map(identified[s.name], s.ratio * base) if s.name in identified
            else subsystem_map(subsystems[s.name], s.ratio * base, s.order) for s in subs]

    z_index, history_index, offset = [], [], 0
    for m in maps:
        z_index.append(slice(offset, offset + m.Phi.shape[0]))
        offset += m.Phi.shape[0]
    for m in maps:
        n_y = m.C_y.shape[0]
        history_index.append(tuple(slice(offset + q * n_y, offset + (q + 1) * n_y) for q in range(depth + 1)))
        offset += (depth + 1) * n_y
    identity = np.eye(offset)
    z = [identity[index] for index in z_index]
    history = [[identity[index] for index in samples] for samples in history_index]  # oldest first

    period = math.lcm(*(s.ratio for s in subs))
    pending: dict[int, list[tuple[int, np.ndarray]]] = {}
    for tick in range(period):
        for stage in plan.stages:
            for s in (subs[i] for i in stage):
                if tick % s.ratio:
                    continue
                order = s.order
                c = np.zeros((order + 1, len(s.inputs), offset))
                for feed in s.feeds:
                    ratio = subs[feed.source].ratio
                    # Gauss–Seidel: a source's sample at the end of a step it has taken already (Plan.lead)
                    newest_sample = (tick + plan.lead(feed.source, s.index)) // ratio
                    newest = depth + newest_sample  # its position in the history
                    P = extrapolation_matrix(order + 1, ratio * base, (tick - newest_sample * ratio) * base)
                    samples = history[feed.source][newest - order:newest + 1]
                    for output, target in zip(feed.outputs, feed.inputs):
                        values = np.stack([sample[output] for sample in samples])
                        c[:, target] = P @ values
                m = maps[s.index]
                z[s.index] = m.Phi @ z[s.index] + np.einsum("qab,qbx->ax", m.Gamma, c)
                w_end = np.einsum("q,qbx->bx", m.span ** np.arange(order + 1), c)
                y_end = m.C_y @ z[s.index] + m.D_y @ w_end
                if plan.sequential:  # Gauss–Seidel: taken before the next stage starts
                    history[s.index].append(y_end)
                else:
                    pending.setdefault(tick + s.ratio, []).append((s.index, y_end))
            for index, y in pending.pop(tick + 1, []):
                history[index].append(y)
    Psi = np.vstack(z + [sample for samples in history for sample in samples[-(depth + 1):]])
    return DiscreteScheme(Psi, period * base * 1e-9, tuple(z_index), tuple(history_index),
                          tuple(identified[s.name].identification for s in subs if s.name in identified))


def scene_scheme(scene: Scene, subsystems: dict[str, Subsystem]) -> DiscreteScheme:
    """``discrete_scheme`` of a scene's built subsystems (the run plan compiled from their ports), its FMUs and
    Python models identified (``manager.analysis.identified``; ``LinearSceneError`` when one cannot be)."""
    if scene.manager.corrects:
        raise LinearSceneError(f"scene {scene.name}: the discrete analysis does not model energy correction "
                               "(manager.correction); expected it disabled")
    plan = compile_plan(scene, {name: (s.inputs, s.outputs, s.effects) for name, s in subsystems.items()})
    external = {name for name, sub in subsystems.items() if isinstance(sub.model, ExternalModel)}
    if not external:
        return discrete_scheme(plan, subsystems)
    attached = coupling_attachments(scene)
    try:
        identified = identified_steps(plan, subsystems, external,
                                      lambda name: build_subsystem(scene, name, attached[name]),
                                      lambda name: scene.subsystems[name].spec.can_save_state)
    except (IdentificationError, FmuError) as error:
        raise LinearSceneError(f"scene {scene.name}: {error}") from None
    return discrete_scheme(plan, subsystems, identified)


def uncompensated_scheme(scene: Scene) -> DiscreteScheme:
    """The exact discrete scheme of ``scene`` run without its compensator (``LinearSceneError``: not linear)."""
    plain = replace(scene, manager=replace(scene.manager, compensation="none"))
    return scene_scheme(plain, {name: build_subsystem(plain, name, attached)
                                for name, attached in coupling_attachments(plain).items()})


def run_scheme(scene: Scene) -> DiscreteScheme | None:
    """The exact discrete scheme of the run ``scene`` describes — compensated when it asks for the compensator,
    as ``analyze`` reports it — or None when the scene is not linear or corrects energy (no transition matrix), or a
    subsystem is identified only as a local linearisation (a verdict on small motions, not on the run) or is a
    source or a sink (its own modes are outside ``Ψ``).
    ``SceneError`` when the compensator cannot be designed."""
    if discrete_unavailable(scene) or scene.manager.corrects:
        return None
    try:
        if scene.manager.compensation == "eigenstructure":
            from zencosim.manager.analysis.compensator import scene_compensator  # needs scipy.optimize
            return scene_compensator(scene).scheme
        scheme = uncompensated_scheme(scene)
    except LinearSceneError:  # a model whose public matrices are not its whole dynamics, one not identified
        return None
    return scheme if all(i.exact and i.role == "loop" for i in scheme.identifications) else None
