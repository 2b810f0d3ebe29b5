"""Turn a scene into runnable objects: co-simulation subsystems, the monolithic model, the linear model."""
from __future__ import annotations

import dataclasses
import math
from functools import reduce

import numpy as np

from compensation.architecture import Architecture
from compensation.linear_model import ForceDisplacementBond, LinearModel
from manager import compensator
from manager.discrete import DiscreteScheme, scene_scheme
from manager.scene import Scene, SceneError
from subsystems.effects import PlacedEffect
from subsystems.integrators import INTEGRATORS
from subsystems.masses import MassesModel, MassesSpec
from subsystems.params import Problem
from subsystems.models import MODELS
from subsystems.ports import Attachments
from subsystems.subsystem import Subsystem


def coupling_attachments(scene: Scene) -> dict[str, Attachments]:
    """What every coupling adds to every subsystem, in scene order.

    A force-side model that starts in equilibrium with its load (``starts_at_rest``) also gets the
    motion side's rest state: its point's initial position and the coupling force that holds it.
    """
    result = {name: Attachments() for name in scene.subsystems}
    for coupling in scene.couplings.values():
        for sub, added in coupling.attachments().items():
            result[sub] = result[sub] + added
    for coupling in scene.couplings.values():
        if coupling.kind == "rigid_joint":  # no force side: both sides are driven by the joint's variables
            continue
        if MODELS[scene.subsystems[coupling.force_sub].settings.model].starts_at_rest:
            motion = _model(scene, coupling.motion_sub, result[coupling.motion_sub])
            rest = dataclasses.replace(motion.rest_state(coupling.motion_point), point=coupling.force_point)
            result[coupling.force_sub] = result[coupling.force_sub] + Attachments(rest_states=(rest,))
    return result


def scene_compensator(scene: Scene, architecture: Architecture | None = None) -> compensator.Compensator:
    """The compensator of a scene, corrected on the scene's own discrete scheme (``architecture``:
    default ``compensator.runtime_architecture``)."""
    base = coupling_attachments(scene)

    def runtime_scheme(added: dict[str, Attachments]) -> DiscreteScheme:
        return scene_scheme(scene, {name: build_subsystem(scene, name, base[name] + added[name])
                                    for name in scene.subsystems})

    return compensator.compensate(scene, compensated_linear_model(scene), runtime_scheme, architecture)


def attachments(scene: Scene) -> dict[str, Attachments]:
    """What every coupling, then the compensator the scene asks for, adds to every subsystem."""
    result = coupling_attachments(scene)
    if scene.manager.compensation == "eigenstructure":
        for sub, added in scene_compensator(scene).attachments.items():
            result[sub] = result[sub] + added
    return result


def _model(scene: Scene, name: str, attached: Attachments):
    sub = scene.subsystems[name]
    return MODELS[sub.settings.model](sub.spec, attached)


def build_subsystem(scene: Scene, name: str, attached: Attachments | None = None) -> Subsystem:
    """The subsystem ``name`` of the scene, with only the effects the scene names."""
    if attached is None:
        attached = attachments(scene)[name]
    settings = scene.subsystems[name].settings
    return Subsystem(name, _model(scene, name, attached), INTEGRATORS[settings.integrator], settings.micro_step_ns)


def build_subsystems(scene: Scene) -> dict[str, Subsystem]:
    attached = attachments(scene)
    return {name: build_subsystem(scene, name, attached[name]) for name in scene.subsystems}


LINEAR_KINDS = ("linear", "external")  # effect kinds of a linear model (an external force is a forcing term)


def linear_unavailable(scene: Scene) -> str | None:
    """Why the scene has no linear model ``M, C, K`` (None when it has one); integrators do not matter."""
    joints = [name for name, c in scene.couplings.items() if c.kind == "rigid_joint"]
    if joints:
        return (f"the scene has a rigid joint ({', '.join(joints)}); its reference is 'solve_ivp', the "
                "subsystems integrated together with the joint held exactly")
    models = {s.settings.model for s in scene.subsystems.values()}
    if models != {MassesModel.name}:
        return f"the monolithic model is assembled for '{MassesModel.name}' subsystems only, got {sorted(models)}"
    nonlinear = sorted(f"{s.name}.{e.name}" for s in scene.subsystems.values() for e in s.spec.effects
                       if e.effect.kind not in LINEAR_KINDS)
    nonlinear += sorted(e.name for c in scene.couplings.values() for e in c.effects if e.effect.kind not in LINEAR_KINDS)
    if nonlinear:
        return f"nonlinear effects {', '.join(nonlinear)}"
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
