"""Integrators against the analytic solution of a single oscillator: orders as slopes, and the
symplectic Euler's bounded energy error on an undamped oscillator."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from zencosim.subsystems.effects import PlacedEffect, Spring
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models.masses import Body, MassesModel, MassesSpec
from zencosim.subsystems.ports import Attachments, ForceInput
from zencosim.subsystems.subsystem import Subsystem

OMEGA = 10.0  # [rad/s]: k = 100 N/m, m = 1 kg
# x0 != 0: with x0 = 0 the kick-drift scheme happens to be second order (it is leapfrog with v0 read as v(h/2))
X0, V0 = 1.0, 2.0  # [m], [m/s]


def _oscillator(integrator: str, micro_step_ns: int) -> Subsystem:
    spec = MassesSpec({"m": Body(mass=1.0, x0=X0, v0=V0)}, (PlacedEffect("k", Spring(stiffness=OMEGA ** 2), ("m", None)),))
    return Subsystem("osc", MassesModel(spec), INTEGRATORS[integrator], micro_step_ns)


def _final_error(integrator: str, micro_step_ns: int, end_ns: int = 1_000_000_000) -> float:
    sub = _oscillator(integrator, micro_step_ns)
    sub.advance(0, end_ns, InputPolynomial(np.empty((1, 0))))
    t = end_ns * 1e-9
    return abs(sub.z[0] - (X0 * math.cos(OMEGA * t) + V0 / OMEGA * math.sin(OMEGA * t)))


@pytest.mark.parametrize("integrator,order", [("symplectic_euler", 1), ("rk4", 4)])
def test_global_error_slope_matches_the_order(integrator, order):
    # steps from 2 ms to 0.25 ms: asymptotic regime (omega h <= 0.02) with RK4's error (>= 1e-11 m) far
    # above round-off; at 0.125 ms RK4 meets the round-off floor (~1e-13 m) and the slope flattens
    steps_ns = [2_000_000, 1_000_000, 500_000, 250_000]
    errors = [_final_error(integrator, h) for h in steps_ns]
    slope = np.polyfit(np.log(steps_ns), np.log(errors), 1)[0]
    assert slope == pytest.approx(order, abs=0.15)  # 0.15: the fitted slope of a clean power law


def test_symplectic_euler_keeps_the_energy_error_bounded():
    # a symplectic method conserves a modified energy: over 1000 periods the energy error oscillates
    # at O(omega h) instead of drifting; 2 omega h bounds it (omega h = 0.01 here)
    sub = _oscillator("symplectic_euler", 1_000_000)
    no_input = InputPolynomial(np.empty((1, 0)))
    energies = [sub.advance(k * 10 ** 8, (k + 1) * 10 ** 8, no_input)[-1] for k in range(6283)]
    relative = np.abs(np.array(energies) / (0.5 * V0 ** 2 + 0.5 * OMEGA ** 2 * X0 ** 2) - 1.0)
    assert relative.max() < 2 * OMEGA * 1e-3


@pytest.mark.parametrize("integrator", sorted(n for n, cls in INTEGRATORS.items() if hasattr(cls, "linear_step")))
def test_linear_step_is_the_step_the_integrator_takes(integrator):
    # the one-step map (Φ, Γ) the exact discrete analysis is built from, against step() itself, for a
    # damped two-body model with terminal and force inputs driven by a quadratic input polynomial
    from zencosim.manager.assembly import build_subsystems
    from zencosim.manager.scene.load import load_scene
    sub = build_subsystems(load_scene("four_mass", [f"subsystems.S1.integrator={integrator}"]))["S1"]
    model, h, tau = sub.model, 1e-3, 2e-3
    rng = np.random.default_rng(7)
    z0 = rng.normal(size=2 * model.n_dof)
    inputs = InputPolynomial(rng.normal(size=(3, len(model.inputs))))
    sub.z[:] = z0
    sub.integrator.step(0.0, tau, h, inputs)
    Phi, Gamma = INTEGRATORS[integrator].linear_step(model.A_a, model.B_a, h)
    nodes = INTEGRATORS[integrator].input_nodes
    expected = Phi @ z0 + sum(G @ inputs.at(tau + node * h) for G, node in zip(Gamma, nodes))
    # same arithmetic in another order: agreement to a few ulps of the largest term (|A_a| h ~ 0.3)
    assert sub.z == pytest.approx(expected, rel=1e-14, abs=1e-14 * np.abs(expected).max())


def _forced_oscillator(micro_step_ns: int, force_coefficients: np.ndarray) -> tuple[Subsystem, InputPolynomial]:
    spec = MassesSpec({"m": Body(mass=2.0, x0=X0, v0=V0)},
                      (PlacedEffect("k", Spring(stiffness=OMEGA ** 2), ("m", None)),))
    model = MassesModel(spec, Attachments(force_inputs=(ForceInput(("f*",), "m", 1.0),)))
    return Subsystem("osc", model, INTEGRATORS["exact"], micro_step_ns), InputPolynomial(force_coefficients[:, None])


def test_exact_integrator_matches_a_tight_reference_and_any_micro_step():
    """A quadratic force over one 0.2 s step: the exact integrator agrees with scipy's DOP853 at rtol
    1e-12 to 1e-10 (the reference's own tolerance, accumulated), and one step equals 16 micro-steps
    (re-expanded input polynomial) to 1e-13 (rounding)."""
    force = np.array([3.0, -20.0, 150.0])  # f(tau) = 3 - 20 tau + 150 tau^2 [N]
    span_ns = 200_000_000
    one, inputs = _forced_oscillator(span_ns, force)
    many, _ = _forced_oscillator(span_ns // 16, force)
    x_one, x_many = one.advance(0, span_ns, inputs), many.advance(0, span_ns, inputs)
    reference = solve_ivp(lambda t, z: [z[1], (-OMEGA ** 2 * z[0] + np.polyval(force[::-1], t)) / 2.0],
                          (0.0, 0.2), [X0, V0], method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
    np.testing.assert_allclose(one.z, reference, rtol=1e-10)
    np.testing.assert_allclose(many.z, one.z, rtol=1e-13)
    assert x_one[-1] == pytest.approx(x_many[-1], rel=1e-13)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4", "exact"])
@pytest.mark.parametrize("rows", [1, 2, 3])
def test_composed_communication_step_equals_micro_stepping(integrator, rows):
    # a linear model is advanced by the composition of its micro-steps (subsystems.subsystem); it must
    # be the same map as stepping: agreement to rounding (1e-12 of the state) over 200 communication
    # steps of 10 micro-steps with polynomial inputs of every order the protocol sends
    from zencosim.manager.assembly import build_subsystems
    from zencosim.manager.scene.load import load_scene
    scene = load_scene("two_mass_damped", ["subsystems.S1.micro_step=0.0001", f"subsystems.S1.integrator={integrator}"])
    composed, stepped = build_subsystems(scene)["S1"], build_subsystems(scene)["S1"]
    stepped._linear = None  # force micro-stepping
    rng = np.random.default_rng(3)
    for k in range(200):
        inputs = InputPolynomial(rng.normal(size=(rows, 2)) * np.array([[1e-2], [1.0], [100.0]])[:rows])
        a = composed.advance(k * 1_000_000, (k + 1) * 1_000_000, inputs)
        b = stepped.advance(k * 1_000_000, (k + 1) * 1_000_000, inputs)
    assert composed._linear is not None
    assert np.allclose(composed.z, stepped.z, rtol=1e-12, atol=1e-12 * np.abs(stepped.z).max())
    assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
