"""The subsystems a scene names, built with what its couplings attach to each of them."""
from __future__ import annotations

import contextlib
import dataclasses

from zencosim.manager.scene.load import Scene, SceneError
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models import model_class
from zencosim.subsystems.models.external.fmu import FmuError
from zencosim.subsystems.params import Problem
from zencosim.subsystems.ports import Attachments
from zencosim.subsystems.subsystem import Subsystem


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
        if coupling.kind != "force_displacement":  # a joint's sides are driven by its variables; a signal has none
            continue
        if scene.subsystems[coupling.force_sub].traits.starts_at_rest:
            motion = _model(scene, coupling.motion_sub, result[coupling.motion_sub])
            with _model_problems(scene, coupling.motion_sub):
                rest = dataclasses.replace(motion.rest_state(coupling.motion_point), point=coupling.force_point)
            result[coupling.force_sub] = result[coupling.force_sub] + Attachments(rest_states=(rest,))
    return result


@contextlib.contextmanager
def _model_problems(scene: Scene, name: str):
    """A model that cannot be built from the scene's parameters says why (ValueError, an overflow), and so does
    an FMU that cannot be instantiated here: a scene error naming the subsystem."""
    try:
        yield
    except SceneError:
        raise
    except (ValueError, ArithmeticError) as error:
        raise SceneError(scene.path, [Problem(f"subsystems.{name}", str(error))]) from None
    except FmuError as error:
        raise SceneError(scene.path, [Problem(f"subsystems.{name}.fmu", str(error))]) from None


def _model(scene: Scene, name: str, attached: Attachments):
    sub = scene.subsystems[name]
    with _model_problems(scene, name):
        return model_class(sub.settings.model)(sub.spec, attached)


def build_subsystem(scene: Scene, name: str, attached: Attachments) -> Subsystem:
    """The subsystem ``name`` of the scene with what is ``attached`` to it (``coupling_attachments`` and
    what a compensator adds), and only the effects the scene names."""
    settings = scene.subsystems[name].settings
    model = _model(scene, name, attached)
    with _model_problems(scene, name):
        # with energy-controlled macro-steps a co-simulation component takes one step per macro-step (check_timing)
        whole_steps = scene.manager.step_control == "energy" and scene.subsystems[name].traits.advances_itself
        return Subsystem(name, model, INTEGRATORS[settings.integrator], settings.micro_step_ns, whole_steps)
