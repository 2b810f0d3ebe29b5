"""The hydraulic crane (paper 002 §4.4): static equilibrium at the start, the spool position it implies,
the spool law of Eq. 33 and the geometry of the arm."""
from __future__ import annotations

import math

import numpy as np
import pytest

from zencosim.manager.assembly import attachments, build_subsystems
from zencosim.manager.results.reference import CoupledSystem
from zencosim.manager.scene.load import load_scene
from zencosim.subsystems.models.hydraulic_cylinder import SpoolLaw


def test_the_solved_spool_position_is_the_papers():
    # gamma0 is solved from the arm's static load (8829 N along the actuator), not given; paper: ~0.45435
    hydraulic = build_subsystems(load_scene("hydraulic_crane"))["H"].model
    assert hydraulic.initial_force == pytest.approx(8829.0, rel=1e-12)
    assert hydraulic.neutral_opening == pytest.approx(0.45435, abs=5e-6)


def test_the_coupled_system_starts_at_rest():
    # with the spool at gamma0 (A(0) = 0) every state derivative vanishes at t = 0
    system = CoupledSystem(load_scene("hydraulic_crane"))
    derivative = system.derivative(0.0, system.z0)
    pressures = system.z0[system.slices[1]]
    assert np.max(np.abs(derivative[system.slices[0]])) < 1e-12  # [rad/s, rad/s^2]
    assert np.max(np.abs(derivative[system.slices[1]])) < 1e-9 * np.max(pressures)  # [Pa/s]


def test_the_rest_state_reaches_the_cylinder_through_the_coupling():
    (rest,) = attachments(load_scene("hydraulic_crane"))["H"].rest_states
    assert rest.point == "rod" and rest.position == pytest.approx((0.5,)) and rest.force == pytest.approx((8829.0,))


def test_spool_law_of_eq_33():
    law = SpoolLaw()
    assert [law.envelope(t) for t in (0.0, 0.5, 1.0, 4.0, 8.0, 8.5, 9.0, 12.0)] == pytest.approx(
        [0.0, 0.05, 0.1, 0.1, 0.1, 0.05, 0.0, 0.0])
    assert law.opening(3.125, 0.4) == pytest.approx(0.4 * (1 - 0.1 * math.sin(2 * math.pi * 2.0 * 3.125)))


def test_a_load_the_pump_cannot_hold_is_refused():
    scene = load_scene("hydraulic_crane", ["subsystems.M.mass_q=2500.0"])
    with pytest.raises(ValueError, match="cannot hold"):
        build_subsystems(scene)
