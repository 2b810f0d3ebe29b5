"""Nonlinear springs and dampers (paper 002 Eqs. 22-23) and the nonlinear path of the point-mass model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from zencosim.manager.assembly import build_subsystems
from zencosim.manager.scene.load import load_scene
from zencosim.subsystems.effects import QuadraticDamper, SqrtSpring


@pytest.mark.parametrize("eta", [-2.0, -1e-6, 0.0, 0.25, 9.0])
def test_sqrt_spring_is_eq_22_and_its_energy_is_the_integral_of_its_force(eta):
    spring = SqrtSpring(stiffness=100.0)
    assert spring.force(eta, 5.0) == pytest.approx(-100.0 * math.copysign(math.sqrt(abs(eta)), eta))
    h = 1e-7  # central difference of the stored energy: f = -dV/d(eta)
    if abs(eta) > 1e-3:
        assert spring.force(eta, 0.0) == pytest.approx(-(spring.potential(eta + h) - spring.potential(eta - h)) / (2 * h),
                                                       rel=1e-6)


@pytest.mark.parametrize("rate", [-3.0, 0.0, 0.5])
def test_quadratic_damper_is_eq_23_and_dissipates(rate):
    damper = QuadraticDamper(damping=0.001)
    assert damper.force(1.0, rate) == pytest.approx(-0.001 * math.copysign(rate * rate, rate))
    assert damper.force(1.0, rate) * rate <= 0.0 and damper.potential(1.0) == 0.0


def test_point_masses_with_nonlinear_coupling_give_the_force_law_and_feedthrough():
    subs = build_subsystems(load_scene("nonlinear_oscillator_case1"))
    m1 = subs["M1"]
    (force_port,) = [p for p in m1.outputs if p.quantity == "force"]
    assert force_port.feedthrough  # the sqrt spring depends on the received x2*
    # at x1 = 0 with x2* = -4 m: eta = x1 - x2* = 4 m, the spring pulls m1 with -100 sqrt(4) = -200 N and m2
    # with +200 N, the force the output carries (what m2 receives); energy: kinetic 5000 J,
    # coupling spring (2/3) 100 * 4^1.5 = 533.3 J, ground spring 0
    y = m1.output_values(np.array([-4.0, 0.0]))
    assert y[0] == pytest.approx(200.0)
    assert y[-1] == pytest.approx(5000.0 + 2.0 / 3.0 * 100.0 * 8.0)


def test_a_nonlinear_scene_has_no_analytic_reference():
    scene = load_scene("nonlinear_oscillator_case2", ["outputs.reference=analytic"])
    from zencosim.manager.run import references
    refs, note = references(scene)
    assert refs == {} and "nonlinear effects" in note
