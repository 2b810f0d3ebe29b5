"""One conformance check over every registered subsystem model (STYLE: Gymnasium's check_env).

Every model must appear in a bundled scene; every subsystem of every bundled scene is then checked:
SI units on all ports, finite outputs, two instances identical, and save/restore exact to the bit.
"""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.manager.assembly import build_subsystems
from zencosim.manager.scene.load import bundled_scene_names, load_scene
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.models import MODELS

SI_UNITS = {"m", "m/s", "m/s^2", "N", "1/kg", "J"}
SUBSYSTEMS = [(name, sub) for name in bundled_scene_names() for sub in load_scene(name).subsystems]


def test_every_registered_model_is_used_by_a_bundled_scene():
    used = {load_scene(name).subsystems[sub].settings.model for name, sub in SUBSYSTEMS}
    assert used == set(MODELS)


def _drive(subsystem, seed: int, steps: int, comm_step_ns: int) -> np.ndarray:
    """Advance with seeded random quadratic input polynomials; return the outputs at each point."""
    rng = np.random.default_rng(seed)
    outputs = []
    for k in range(steps):
        coefficients = rng.normal(size=(3, len(subsystem.inputs))) * np.array([[1.0], [10.0], [100.0]])
        outputs.append(subsystem.advance(k * comm_step_ns, (k + 1) * comm_step_ns, InputPolynomial(coefficients)))
    return np.array(outputs)


@pytest.mark.parametrize("scene_name,sub_name", SUBSYSTEMS)
def test_model_conformance(scene_name, sub_name):
    scene = load_scene(scene_name)
    comm = scene.comm_step_ns(sub_name)
    first, second = build_subsystems(scene)[sub_name], build_subsystems(scene)[sub_name]

    ports = first.inputs + first.outputs
    assert {p.unit for p in ports} <= SI_UNITS
    assert len({p.name for p in ports}) == len(ports), "port names must be unique"
    assert first.outputs[-1].quantity == "energy"

    a = _drive(first, seed=7, steps=20, comm_step_ns=comm)
    b = _drive(second, seed=7, steps=20, comm_step_ns=comm)
    assert np.isfinite(a).all()
    assert a.tobytes() == b.tobytes(), "two instances of the same subsystem must give identical outputs"

    saved = first.save()
    ahead = _drive_from(first, 20, comm)
    first.restore(saved)
    assert first.save() == saved
    again = _drive_from(first, 20, comm)
    assert ahead.tobytes() == again.tobytes(), "restore must return the exact state"


def _drive_from(subsystem, start: int, comm: int) -> np.ndarray:
    rng = np.random.default_rng(11)
    out = []
    for k in range(start, start + 5):
        coefficients = rng.normal(size=(1, len(subsystem.inputs)))
        out.append(subsystem.advance(k * comm, (k + 1) * comm, InputPolynomial(coefficients)))
    return np.array(out)


def test_advance_rejects_a_step_that_is_not_a_multiple_of_the_micro_step():
    scene = load_scene("two_mass_damped", ["subsystems.S2.micro_step=0.0005"])
    sub = build_subsystems(scene)["S2"]
    with pytest.raises(ValueError, match="not a positive multiple of the micro-step"):
        sub.advance(0, 1_250_000, InputPolynomial(np.zeros((1, 1))))
