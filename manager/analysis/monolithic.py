"""The monolithic counterpart of a scene: every body and effect in one model, and its linear model ``M, C, K``.

The monolithic model is the reference a co-simulation is measured against (``manager.results.reference``)
and the linear model is what the eigenstructure analysis and compensator work on (paper 000 Eq. 11).
"""
from __future__ import annotations

import math
from functools import reduce

import numpy as np

from zencosim.compensation.linear_model import ForceDisplacementBond, LinearModel
from zencosim.manager.scene.load import Scene, SceneError
from zencosim.subsystems.effects import PlacedEffect
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models import model_class
from zencosim.subsystems.models.external.model import ExternalModel
from zencosim.subsystems.models.masses import MassesModel, MassesSpec
from zencosim.subsystems.params import Problem
from zencosim.subsystems.ports import Attachments
from zencosim.subsystems.subsystem import Subsystem

LINEAR_KINDS = ("linear", "external")  # effect kinds of a linear model (an external force is a forcing term)


def discrete_unavailable(scene: Scene) -> str | None:
    """Why the explicit scheme of the scene has no transition matrix, exact or identified (None when it has one):
    ``masses`` subsystems with linear effects enter exactly, external models (FMUs, Python models) identified
    (``manager.analysis.identified``); other built-in models and rigid joints do not."""
    joints = [name for name, c in scene.couplings.items() if c.kind == "rigid_joint"]
    if joints:
        return (f"the scene has a rigid joint ({', '.join(joints)}); its reference is 'solve_ivp', the "
                "subsystems integrated together with the joint held exactly")
    if scene.manager.scheme == "implicit":
        return "manager.scheme = 'implicit': the analysis is of the explicit schemes (jacobi, gauss-seidel)"
    built_in = sorted({s.settings.model for s in scene.subsystems.values() if s.settings.model != MassesModel.name
                       and not issubclass(model_class(s.settings.model), ExternalModel)})
    if built_in:
        return (f"built-in models {built_in} are not linear; expected '{MassesModel.name}' subsystems or external "
                "models (FMUs, Python models), which are identified")
    nonlinear = sorted(f"{s.name}.{e.name}" for s in scene.subsystems.values() for e in getattr(s.spec, "effects", ())
                       if e.effect.kind not in LINEAR_KINDS)
    nonlinear += sorted(e.name for c in scene.couplings.values() for e in c.effects if e.effect.kind not in LINEAR_KINDS)
    if nonlinear:
        return f"nonlinear effects {', '.join(nonlinear)}"
    return None


def linear_unavailable(scene: Scene) -> str | None:
    """Why the scene has no linear model ``M, C, K`` (None when it has one); integrators do not matter."""
    reason = discrete_unavailable(scene)
    if reason:
        return reason
    models = {s.settings.model for s in scene.subsystems.values()}
    if models != {MassesModel.name}:
        return f"the monolithic model is assembled for '{MassesModel.name}' subsystems only, got {sorted(models)}"
    return None


def monolithic_unavailable(scene: Scene) -> str | None:
    """Why the scene has no monolithic counterpart (None when it has one): a linear model, one integrator."""
    reason = linear_unavailable(scene)
    if reason:
        return reason
    integrators = {s.settings.integrator for s in scene.subsystems.values()}
    if len(integrators) != 1:
        return f"subsystems use different integrators {sorted(integrators)}"
    return None


def _qualify(sub: str, point: str | None) -> str | None:
    return None if point is None else f"{sub}.{point}"


def monolithic_spec(scene: Scene) -> MassesSpec:
    """All bodies and effects of all subsystems in one model; points are named ``<subsystem>.<body>``."""
    bodies, effects = {}, []
    for sub in scene.subsystems.values():
        for body_name, body in sub.spec.bodies.items():
            bodies[_qualify(sub.name, body_name)] = body
        for placed in sub.spec.effects:
            effects.append(PlacedEffect(f"{sub.name}.{placed.name}", placed.effect,
                                        tuple(_qualify(sub.name, p) for p in placed.endpoints)))
    return MassesSpec(bodies, tuple(effects))


def monolithic_model(scene: Scene) -> MassesModel:
    """All bodies and effects in one model, the couplings' elements acting directly between the bodies."""
    attached = reduce(lambda a, c: a + c.monolithic_attachments(_qualify), scene.couplings.values(), Attachments())
    return MassesModel(monolithic_spec(scene), attached)


def build_monolithic(scene: Scene) -> Subsystem:
    """The monolithic system with the subsystems' integrator and the finest micro-step that divides all.

    The couplings' elements act directly between the bodies; the model outputs every coupling signal.
    """
    reason = monolithic_unavailable(scene)
    if reason:
        raise ValueError(f"scene {scene.name}: no monolithic model: {reason}")
    model = monolithic_model(scene)
    micro_step_ns = math.gcd(*(s.settings.micro_step_ns for s in scene.subsystems.values()))
    integrator = next(iter(scene.subsystems.values())).settings.integrator
    return Subsystem("monolithic", model, INTEGRATORS[integrator], micro_step_ns)


def compensated_linear_model(scene: Scene) -> LinearModel:
    """``linear_model`` of a scene that asks for compensation; ``SceneError`` when it is not linear."""
    reason = linear_unavailable(scene)
    if reason:
        raise SceneError(scene.path, [Problem("manager.compensation", f"expected a linear scene: {reason}")])
    return linear_model(scene)


def linear_model(scene: Scene) -> LinearModel:
    """``M, C, K`` of the monolithic system (paper 000 Eq. 11 generalised) and its force–displacement bonds."""
    monolithic = monolithic_model(scene)
    names = monolithic.body_names
    index = {name: i for i, name in enumerate(names)}
    bonds = []
    for coupling in scene.couplings.values():
        K2, C2 = np.zeros((2, 2)), np.zeros((2, 2))  # the coupling element alone, between points 0 and 1
        for placed in coupling.effects:
            if placed.effect.kind != "linear":
                raise ValueError(f"scene {scene.name}: coupling {coupling.name} is not linear ({placed.name})")
            placed.effect.stamp(K2, C2, 0, 1)
        bonds.append(ForceDisplacementBond(coupling.name, index[_qualify(coupling.force_sub, coupling.force_point)],
                                           index[_qualify(coupling.motion_sub, coupling.motion_point)],
                                           K2[0, 0], C2[0, 0]))
    return LinearModel(monolithic.M, monolithic.C, monolithic.K, names, tuple(n.split(".")[0] for n in names),
                       tuple(bonds), scene.manager.macro_step)
