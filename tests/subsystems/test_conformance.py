"""One conformance check over every registered subsystem model (STYLE: Gymnasium's check_env).

Every model must appear in a bundled scene; every subsystem of every bundled scene is then checked by
``subsystems.models.conformance.check_subsystem``: SI units on all ports, finite outputs, two instances
identical, honest feedthrough declarations, and save/restore exact to the bit. A user's models join
with ``pytest --model REF``.
"""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.manager.assembly import build_subsystems
from zencosim.manager.scene.load import bundled_scene_names, load_scene
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.models import MODELS
from zencosim.subsystems.models.conformance import check_component, check_subsystem

SUBSYSTEMS = [(name, sub) for name in bundled_scene_names() for sub in load_scene(name).subsystems]


def test_every_registered_model_is_used_by_a_bundled_scene():
    used = {load_scene(name).subsystems[sub].settings.model for name, sub in SUBSYSTEMS}
    assert used == set(MODELS)


@pytest.mark.parametrize("scene_name,sub_name", SUBSYSTEMS)
def test_model_conformance(scene_name, sub_name):
    scene = load_scene(scene_name)
    assert check_subsystem(lambda: build_subsystems(scene)[sub_name], scene.comm_step_ns(sub_name)) == []


def test_a_users_model_given_with_the_model_option_conforms(user_model):
    """``pytest --model package.module:Class`` (or ``--model path.fmu``, repeatable) runs the conformance
    check over a user's model as over the built-in ones."""
    assert check_component(user_model, {}) == []


def test_advance_rejects_a_step_that_is_not_a_multiple_of_the_micro_step():
    scene = load_scene("two_mass_damped", ["subsystems.S2.micro_step=0.0005"])
    sub = build_subsystems(scene)["S2"]
    with pytest.raises(ValueError, match="not a positive multiple of the micro-step"):
        sub.advance(0, 1_250_000, InputPolynomial(np.zeros((1, 1))))
