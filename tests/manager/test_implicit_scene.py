"""Scenes of the implicit scheme: what a rigid joint needs is checked when the scene is loaded, and every
problem names its key."""
from __future__ import annotations

import pytest

from zencosim.manager.scene.load import SceneError, load_scene


def _problems(name: str, overrides: list[str]) -> dict[str, str]:
    with pytest.raises(SceneError) as caught:
        load_scene(name, overrides)
    return {p.key: p.reason for p in caught.value.problems}


@pytest.mark.parametrize("scene, overrides, key, reason", [
    ("constrained_two_mass", ["manager.scheme=jacobi"], "couplings.joint.type",
     "a rigid joint needs manager.scheme = 'implicit'"),
    ("constrained_two_mass", ["manager.scheme=jacobi"], "manager.implicit", "only with manager.scheme = 'implicit'"),
    ("two_mass_damped", ["manager.scheme=implicit"], "couplings.c.type", "rigid joints only, got 'force_displacement'"),
    ("two_mass_damped", ["manager.scheme=implicit"], "couplings", "exactly one rigid joint, got 0"),
    ("constrained_two_mass", ["manager.implicit.method=weighted-multiplier",
                              "couplings.joint.decomposition=displacement-displacement"], "couplings.joint.decomposition",
     "method 'weighted-multiplier' is not defined for the displacement-displacement decomposition (paper 003 §2.3)"),
    ("constrained_two_mass", ["subsystems.S1.comm_ratio=2"], "subsystems.S1.comm_ratio", "the implicit scheme is single-rate"),
    ("constrained_two_mass", ["couplings.joint.axes=['x', 'y']"], "couplings.joint.axes",
     "m2 moves in 1 dimension(s), the joint has 2 axes"),
    ("constrained_two_mass", ["couplings.joint.side_2=S1.m1"], "couplings.joint.side_2", "a different subsystem"),
    ("constrained_two_mass", ["outputs.reference=analytic"], "outputs.reference", "expected 'solve_ivp'"),
    ("constrained_two_mass", ["subsystems.S1.extrapolation=2"], "subsystems.S1.extrapolation", "is manager.extrapolation"),
    ("constrained_two_mass", ["manager.correction.enabled=true"], "manager.correction", "belongs to the explicit scheme"),
    ("constrained_two_mass", ["manager.implicit.index=4"], "manager.implicit.index", "<= 3"),
    ("constrained_two_mass", ["manager.implicit.method=newton"], "manager.implicit.method", "'projection'"),
    ("double_pendulum", ["couplings.joint.side_1=L1.A"], "couplings.joint.decomposition",
     "L1.A: is the ground pivot and does not move"),
    ("double_pendulum", ["subsystems.L1.x0=0.5"], "subsystems.L1.x0", "a pivoted link's centre follows"),
    ("double_pendulum", ["subsystems.L2.integrator=exact"], "subsystems.L2.integrator",
     "'exact' needs a linear, time-invariant model: the equations of motion of a rotating link are nonlinear"),
    ("two_mass_chirp", ["subsystems.S2.integrator=exact"], "subsystems.S2.integrator", "effect chirp is a force of time"),
    ("nonlinear_oscillator_case1", ["subsystems.M1.integrator=exact"], "subsystems.M1.integrator", "is nonlinear"),
])
def test_problems_of_implicit_scenes_are_named(scene, overrides, key, reason):
    problems = _problems(scene, overrides)
    assert key in problems, problems
    assert reason in problems[key]


def test_the_implicit_table_defaults_and_the_method_in_si_units():
    scene = load_scene("constrained_two_mass", ["manager.implicit.index=2"])
    assert scene.manager.extrapolation == 1  # k
    method = scene.manager.implicit.coupling_method()
    assert (method.beta, method.gamma) == (0.01, 0.0)  # beta = 2 mu [s], index 2: gamma = 0 (§3.4.1)
