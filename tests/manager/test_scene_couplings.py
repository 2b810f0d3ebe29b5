"""Scene validation of what paper 002's benchmarks added: vector coupling signals, couplings whose force
side computes the force itself, per-subsystem extrapolation, and the correction and spike keys."""
from __future__ import annotations

import pytest

from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import SceneError, load_scene


def _problems(name: str, overrides: list[str]) -> dict[str, str]:
    with pytest.raises(SceneError) as caught:
        load_scene(name, overrides)
    return {p.key: p.reason for p in caught.value.problems}


def test_planar_signals_have_one_port_per_component():
    plan, _ = plan_scene(load_scene("coupled_pendula"))
    (bond,) = plan.bonds
    assert len(bond.components) == 2
    m1 = plan.by_name("M1")
    assert [p.name for p in m1.inputs] == ["x2*", "y2*", "vx2*", "vy2*"]


def test_components_must_match_the_model_and_each_other():
    problems = _problems("coupled_pendula", ["couplings.c.force=f"])
    assert "1, 'displacement': 2" in problems["couplings.c.force"]
    problems = _problems("double_oscillator", ["subsystems.M1.model=pendulum"])
    assert "subsystems.M1.bodies" in problems or "subsystems.M1.mass" in problems  # a pendulum has no bodies


def test_a_point_mass_force_side_needs_a_coupling_element_and_a_line_has_no_free_length():
    problems = _problems("double_oscillator", ["couplings.c.effects.kc.free_length=1.0"])
    assert "needs points in the plane" in problems["couplings.c.effects.kc.free_length"]


def test_the_cylinder_computes_its_force_and_cannot_be_the_motion_side():
    problems = _problems("hydraulic_crane", ["couplings.actuator.effects.k.type=spring",
                                             "couplings.actuator.effects.k.stiffness=1.0"])
    assert "computes the coupling force itself" in problems["couplings.actuator.effects"]
    problems = _problems("hydraulic_crane", ["couplings.actuator.force_side=M.actuator",
                                             "couplings.actuator.motion_side=H.rod"])
    assert "cannot be the force side" in problems["couplings.actuator.force_side"]
    assert "cannot be the motion side" in problems["couplings.actuator.motion_side"]


def test_a_first_order_model_refuses_symplectic_euler():
    problems = _problems("hydraulic_crane", ["subsystems.H.integrator=symplectic_euler"])
    assert "model hydraulic_cylinder is first order" in problems["subsystems.H.integrator"]


def test_extrapolation_per_subsystem():
    plan, _ = plan_scene(load_scene("hydraulic_crane"))
    assert (plan.by_name("M").order, plan.by_name("H").order) == (0, 1)
    assert "<= 2" in _problems("hydraulic_crane", ["subsystems.H.extrapolation=3"])["subsystems.H.extrapolation"]


def test_correction_and_spike_keys_are_checked():
    problems = _problems("double_oscillator", ["manager.correction.mu=1.5", "manager.correction.nu=-0.1",
                                               "manager.correction.cap_force=-1", "manager.spikes.window=0",
                                               "manager.correction.gain=1"])
    assert set(problems) == {"manager.correction.mu", "manager.correction.nu", "manager.correction.cap_force",
                             "manager.spikes.window", "manager.correction.gain"}
    assert "auto" not in problems["manager.correction.nu"]
    scene = load_scene("double_oscillator", ["manager.correction.enabled=true", "manager.correction.mu=0.3"])
    assert scene.manager.corrects and scene.manager.correction.mu == 0.3
