"""Eigenstructure compensation at run time (paper 000 §3, §5.1 Eqs. 36–40, §6.1; docs/compensation.md).

``manager.compensation = "eigenstructure"`` designs the compensator before the run
(``compensation.eigenstructure.assignment.design_compensator`` on the scene's linear model, the interface of the
scene's extrapolation order and macro-step) and realises every feedback term ``r(s) x_m`` of
every force ``u`` acting on DOF ``p`` (``r = s^2 d + s f + g``) inside the subsystems:

* collocated (``p`` and ``m`` in one subsystem, no hold): a ``Feedback`` effect on ``p`` from
  ``m`` in that subsystem, at every micro-step; the acceleration gain is an added mass;
* ``x_j*`` of the force side (``m`` the bond's motion DOF, received through the interface): a
  ``Feedback`` effect on ``p`` from the terminal ``x_j*, v_j*``; the acceleration of ``x_j*``
  is not available (it would close an algebraic loop through the coupling force at t = 0), so
  the architecture fixes its gain at zero (``full_feedback(..., exchanged_acceleration=False)``);
* non-collocated (``p`` the bond's motion DOF ``j``, ``m`` on the force side: Eqs. 37–40): a
  ``Feedback`` effect on the terminal of ``j`` in the force side, relayed through the coupling
  force. The motion side applies ``σ f̃_c*`` (``σ``, the coupling's ``ForceInput`` sign: +1, as a
  connection copies a value unchanged; the paper's ``f_c`` acts on the force side, so the runtime's
  signal is ``-f_c``) and must receive ``σ f_c* + u_{2,1}*``, so the term joins the coupling force with
  the sign ``1/σ`` (with the paper's ``f_c``: subtracted, not "added" as §5.1's prose says).

Discrete correction. ``D(s)`` models the exchange but not this runtime exactly: the feedthrough
output ``f_c(t_{k+1})`` uses ``x_j(t_k)`` (``D(s) e^{-sT}`` rather than Eq. 13's ``D^2`` on that
path) and symplectic Euler at ``h = T_s`` adds its own ``O(h)`` shift; a design on ``D(s)`` leaves
the runtime's poles ``±0.0049 1/s`` off at 1 ms (``±0.019`` at 4 ms), which makes the undamped
two-mass system slightly unstable. ``compensate`` therefore closes the loop on the exact discrete
analysis: it designs for target poles ``λ̃``, realises the gains, computes the primary poles ``ν``
of the runtime's transition matrix (``manager.analysis.discrete``) and solves ``ν(λ̃) = λ`` by Broyden's
method (Jacobian ``∂ν/∂λ̃`` started at the identity: the ``D(s)`` model is nearly right) until every
``|ν_i - λ_i| <= POLE_TOLERANCE`` (at most ``MAX_ITERATIONS`` designs). The assigned poles are then
those of the run, not of a model of it.

A term the realisation cannot place raises ``SceneError``; so does an architecture that cannot
assign the eigenstructure (Eq. 33), a design whose latent roots miss the margin, or a corrected
compensator whose discrete scheme is unstable.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from zencosim.compensation.eigenstructure.architecture import Architecture, full_feedback
from zencosim.compensation.eigenstructure.assignment import CompensatorDesign, NotAssignableError, design_compensator
from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.modes import monolithic_eigenstructure
from zencosim.compensation.linear_model import LinearModel
from zencosim.manager.analysis.discrete import DiscreteScheme, scene_scheme
from zencosim.manager.analysis.monolithic import compensated_linear_model
from zencosim.manager.plan.attachments import build_subsystem, coupling_attachments
from zencosim.manager.scene.load import Scene, SceneError
from zencosim.manager.scene.settings import extrapolation_order
from zencosim.subsystems.effects.feedback import Feedback
from zencosim.subsystems.params import Problem
from zencosim.subsystems.ports import Attachments, RelayedForce

PADE_ORDER = 6  # of the latent-root check in the design (paper 000 §2.3.2)
DESIGN_SEED = 0  # of the design's null-space search
POLE_TOLERANCE = 1e-7  # [1/s]: |ν_i - λ_i| at which the correction stops (ρ - 1 <= 1e-10 at 1 ms for λ on the axis)
MAX_ITERATIONS = 16  # designs; measured: 4 for the two-mass cases, 8 for four_mass


def _refuse(scene: Scene, reason: str) -> SceneError:
    return SceneError(scene.path, [Problem("manager.compensation", reason)])


def runtime_architecture(model: LinearModel) -> Architecture:
    """Eq. 24 / Eq. 47 without the acceleration of the exchanged displacement (see the module text)."""
    return full_feedback(model, exchanged_acceleration=False)


def interface_of(scene: Scene) -> InterfaceModel:
    """``D(s)`` of the scene's exchange: its (single, ``check_compensation``) extrapolation order and
    macro-step, no latency."""
    first = next(iter(scene.subsystems.values()))
    return InterfaceModel(extrapolation_order(scene.manager, first), scene.manager.macro_step)


def design(scene: Scene, model: LinearModel, poles: np.ndarray | None = None,
           architecture: Architecture | None = None) -> CompensatorDesign:
    """The compensator of a scene for target ``poles`` (default monolithic) with ``architecture``
    (default ``runtime_architecture``); ``SceneError`` when it cannot be designed."""
    architecture = runtime_architecture(model) if architecture is None else architecture
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow there ends in the LinAlgError below
            result = design_compensator(model, interface_of(scene), architecture, PADE_ORDER, seed=DESIGN_SEED,
                                        poles=poles)
    except NotAssignableError as error:
        raise _refuse(scene, str(error)) from None
    except np.linalg.LinAlgError as error:  # a scene whose k/m spans too many orders for the design's algebra
        raise _refuse(scene, f"the compensator cannot be designed for this scene: its linear algebra failed "
                             f"({error}); the stiffness-to-mass ratios span too many orders of magnitude") from None
    if not result.margin_met:
        raise _refuse(scene, f"the compensated latent roots reach Re s = {result.latent_abscissa:.4g} 1/s; "
                      f"expected <= {-result.margin:.4g} 1/s")
    return result


def attachments(scene: Scene, model: LinearModel, designed: CompensatorDesign) -> dict[str, Attachments]:
    """The ``Feedback`` effects and relayed forces that realise ``designed`` in each subsystem."""
    (coupling,) = scene.couplings.values()
    sides = coupling.attachments()
    terminal = sides[coupling.force_sub].terminals[0].name
    (reaction,) = sides[coupling.motion_sub].force_inputs
    motion_dof = model.dof_names.index(f"{coupling.motion_sub}.{coupling.motion_point}")
    architecture = designed.architecture
    n = architecture.n_terms
    effects: dict[str, list] = {name: [] for name in scene.subsystems}
    relayed: list[str] = []
    t = 0
    for u in architecture.forces:
        for term in u.feedback:
            source_sub, source = model.dof_names[term.dof].split(".", 1)
            for act in u.actuations:
                target_sub, target = model.dof_names[act.dof].split(".", 1)
                gains = Feedback(act.sign * designed.k[t], act.sign * designed.k[n + t], act.sign * designed.k[2 * n + t])
                name = f"compensation.{u.name}.r{t + 1}"
                hops = int(term.through_hold) + int(act.through_hold)
                if hops == 0 and source_sub == target_sub:
                    effects[target_sub].append((name, gains, (target, source)))
                elif (hops == 1 and term.through_hold and term.dof == motion_dof
                      and target_sub == coupling.force_sub):
                    effects[target_sub].append((name, gains, (target, terminal)))
                elif hops == 1 and act.dof == motion_dof and source_sub == coupling.force_sub:
                    effects[source_sub].append((name, gains, (terminal, source)))
                    relayed.append(name)
                else:
                    raise _refuse(scene, f"{architecture.name}: term {name} ({model.dof_names[term.dof]} "
                                  f"{'through the interface ' if hops else ''}on {model.dof_names[act.dof]}) has no "
                                  "realisation in a force–displacement coupling")
            t += 1
    result = {name: Attachments(effects=tuple(added)) for name, added in effects.items()}
    if relayed:
        relay = RelayedForce(coupling.settings.force, terminal, tuple(relayed), reaction.sign)
        result[coupling.force_sub] = result[coupling.force_sub] + Attachments(relayed_forces=(relay,))
    return result


@dataclass(frozen=True)
class Compensator:
    """A compensator corrected on the exact discrete scheme, and what it achieves."""

    design: CompensatorDesign  # the last design (its targets are ``targets``)
    attachments: dict[str, Attachments]  # its realisation, per subsystem
    scheme: DiscreteScheme  # the compensated runtime's transition matrix
    monolithic: np.ndarray  # λ_i [1/s]
    targets: np.ndarray  # λ̃_i the last design assigned in the D(s) model [1/s]
    poles: np.ndarray  # ν_i: primary poles of the compensated runtime, paired with λ_i [1/s]
    iterations: int

    @property
    def pole_error(self) -> float:
        """``max |ν_i - λ_i|`` [1/s]."""
        return float(np.max(np.abs(self.poles - self.monolithic)))


def compensate(scene: Scene, model: LinearModel, runtime_scheme: Callable[[dict[str, Attachments]], DiscreteScheme],
               architecture: Architecture | None = None) -> Compensator:
    """Design, realise and correct the compensator (module text); ``runtime_scheme`` builds the
    transition matrix of the scene's subsystems with the given compensator attachments."""
    monolithic = monolithic_eigenstructure(model).poles
    targets, jacobian, previous = monolithic.copy(), np.eye(len(monolithic), dtype=complex), None
    for iteration in range(1, MAX_ITERATIONS + 1):
        try:
            designed = design(scene, model, targets, architecture)
        except SceneError as error:
            if previous is None:  # the monolithic poles themselves: the design's own reason
                raise
            raise _refuse(scene, _correction_failed(scene, iteration, monolithic, previous[1], targets,
                                                    error.problems[0].reason)) from None
        added = attachments(scene, model, designed)
        scheme = runtime_scheme(added)
        poles = scheme.primary_poles(monolithic)
        error = poles - monolithic
        if np.max(np.abs(error)) <= POLE_TOLERANCE or iteration == MAX_ITERATIONS:
            break
        if previous is not None:  # Broyden's update of ∂ν/∂λ̃ along the last step
            step, change = targets - previous[0], poles - previous[1]
            jacobian += np.outer(change - jacobian @ step, step.conj()) / np.vdot(step, step).real
        previous = (targets, poles)
        targets = targets - np.linalg.solve(jacobian, error)
    if not scheme.stable:
        raise _refuse(scene, f"the compensated scheme is unstable: spectral radius {scheme.spectral_radius:.12g}, "
                      "expected <= 1")
    return Compensator(designed, added, scheme, monolithic, targets, poles, iteration)


def _correction_failed(scene: Scene, iteration: int, monolithic: np.ndarray, discrete: np.ndarray,
                       targets: np.ndarray, reason: str) -> str:
    """Why the correction on the discrete scheme stopped: the design at the monolithic poles succeeded, the
    runtime's discrete poles were far from them, and the shifted targets could not be assigned."""
    def listed(poles: np.ndarray) -> str:
        return ", ".join(f"{p.real:.4g}{p.imag:+.4g}j" for p in poles)
    unpaired = not np.allclose(np.sort_complex(targets), np.sort_complex(targets.conj()), rtol=1e-9, atol=1e-9)
    return (f"the compensator assigns the monolithic poles λ ({listed(monolithic)} 1/s) in the D(s) model, but the "
            f"runtime's exact discrete poles ν with design {iteration - 1} are far from them (max |ν - λ| = {np.max(np.abs(discrete - monolithic)):.4g}"
            f" 1/s at T_s = {scene.manager.macro_step:g} s), and design {iteration} of the correction on the discrete "
            f"scheme asks for targets {listed(targets)} 1/s"
            + (" that are no longer complex-conjugate pairs" if unpaired else "")
            + f", which it cannot assign ({reason.split(': ', 1)[-1]}); a shorter macro-step brings ν closer to λ")


def scene_compensator(scene: Scene, architecture: Architecture | None = None) -> Compensator:
    """The compensator of a scene, corrected on the scene's own discrete scheme (``architecture``:
    default ``runtime_architecture``)."""
    base = coupling_attachments(scene)

    def runtime_scheme(added: dict[str, Attachments]) -> DiscreteScheme:
        return scene_scheme(scene, {name: build_subsystem(scene, name, base[name] + added[name])
                                    for name in scene.subsystems})

    return compensate(scene, compensated_linear_model(scene), runtime_scheme, architecture)
