"""References: the analytic solution against closed forms and scipy, and the monolithic run against it."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.integrate import solve_ivp

from zencosim.compensation.analytic import free_response_blocks, linear_response
from zencosim.manager.analysis.monolithic import build_monolithic, linear_model
from zencosim.manager.results.reference import analytic_reference, monolithic_reference
from zencosim.manager.results.summary import nrms
from zencosim.manager.scene.load import load_scene
from zencosim.subsystems.inputs import InputPolynomial


def test_free_response_matches_the_closed_form_of_a_damped_oscillator():
    m, c, k = 2.0, 0.4, 50.0  # [kg], [N s/m], [N/m]
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    Z = linear_response(A, np.array([0.3, -1.0]), 1e-3, 5000)
    sigma, omega_d = c / (2 * m), math.sqrt(k / m - (c / (2 * m)) ** 2)
    t = np.arange(5001) * 1e-3
    x = np.exp(-sigma * t) * (0.3 * np.cos(omega_d * t) + (-1.0 + sigma * 0.3) / omega_d * np.sin(omega_d * t))
    # 5000 products with exp(A h): round-off grows like k eps, far below 1e-12 m
    assert np.max(np.abs(Z[:, 0] - x)) < 1e-12


def test_forced_response_matches_scipy_on_the_chirp_scene():
    scene = load_scene("two_mass_chirp", ["manager.duration=2.0"])
    ref = analytic_reference(scene)
    model = linear_model(scene)
    chirp = build_monolithic(scene).model.external[0][0]
    A = model.state_matrix()
    b = np.zeros(4)
    b[3] = 1.0 / model.M[1, 1]
    t = np.arange(2001) * 1e-3
    solution = solve_ivp(lambda tt, z: A @ z + b * chirp.force(tt), (0, 2.0), np.zeros(4), method="DOP853",
                         t_eval=t, rtol=1e-12, atol=1e-15)
    # DOP853 at rtol 1e-12 is accurate to ~1e-13 relative; the quadrature to ~1e-16: agree to 1e-9 of the peak
    peak = np.max(np.abs(solution.y[1]))
    assert np.max(np.abs(ref.signals["x2"] - solution.y[1])) < 1e-9 * peak


def test_monolithic_symplectic_euler_against_the_analytic_solution():
    scene = load_scene("two_mass_damped")
    x2 = nrms(monolithic_reference(scene).signals["x2"], analytic_reference(scene).signals["x2"])
    assert x2 < 0.01  # issue 2; we measure 0.0026 (first-order integrator, h = 1 ms, omega h <= 0.033)


def test_nrms_of_a_constant_offset():
    x_ref = np.linspace(-1.0, 1.0, 1001)  # range exactly 2
    assert nrms(x_ref + 0.1, x_ref) == pytest.approx(0.05, rel=1e-12)


def test_linear_model_of_the_four_mass_chain_is_paper_000_eq_44_45():
    model = linear_model(load_scene("four_mass"))
    k = [100.0, 200.0, 300.0, 400.0, 500.0]
    expected_K = np.array([[k[0] + k[1], -k[1], 0, 0], [-k[1], k[1] + k[2], -k[2], 0],
                           [0, -k[2], k[2] + k[3], -k[3]], [0, 0, -k[3], k[3] + k[4]]])
    assert np.array_equal(model.K, expected_K)
    assert np.allclose(model.C, expected_K * 1e-4)
    assert np.array_equal(np.diag(model.M), [1.0, 2.0, 3.0, 4.0])
    (bond,) = model.bonds
    assert (bond.force_dof, bond.motion_dof, bond.stiffness, bond.damping) == (1, 2, 300.0, 0.03)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 70), st.integers(1, 16))
def test_free_response_blocks_are_the_states_one_product_after_another(n_steps, rows):
    """Every state once, in order, in blocks of ``rows`` (the last shorter), equal to the products one after
    another to rounding: a damped oscillator's step matrix, whose powers decay, so 1e-13 of the initial state's size
    bounds the difference of any order of adding."""
    Phi = np.array([[0.99, 0.01], [-0.5, 0.98]])
    z = np.array([0.3, -1.0])
    expected = [z]
    for _ in range(n_steps):
        expected.append(Phi @ expected[-1])
    blocks = list(free_response_blocks(lambda m: np.linalg.matrix_power(Phi, m), z, n_steps, rows))
    assert [len(block) for block in blocks[:-1]] == [rows] * (len(blocks) - 1) and 1 <= len(blocks[-1]) <= rows
    assert np.abs(np.concatenate(blocks) - np.array(expected)).max() <= 1e-13


@pytest.mark.parametrize("name", ["two_mass_damped", "four_mass", "multiple_oscillator_n5", "double_oscillator"])
def test_the_monolithic_reference_is_the_monolithic_model_stepped_and_evaluated_sample_by_sample(name):
    """The reference takes the step matrix's powers and evaluates outputs a block of samples at a time (a few
    products, not a run of the model); it equals stepping the monolithic subsystem with ``advance`` and its outputs,
    sample by sample, to rounding (powers and products add in another order: a few ulps of each signal's range, far
    inside 1e-12)."""
    scene = load_scene(name, ["manager.duration=3.0"])
    fast = monolithic_reference(scene)
    mono = build_monolithic(scene)
    base = scene.manager.macro_step_ns
    none = InputPolynomial(np.empty((1, 0)))
    rows = [mono.output_values(np.empty(0))] + [mono.advance(k * base, (k + 1) * base, none).copy()
                                                for k in range(scene.manager.duration_ns // base)]
    stepped = np.array(rows)
    columns = {port.name: j for j, port in enumerate(mono.outputs)}
    for signal, values in [*fast.signals.items(), ("energy", fast.energy)]:
        expected = stepped[:, columns[signal] if signal != "energy" else -1]
        assert np.max(np.abs(values - expected)) <= 1e-12 * max(np.ptp(expected), np.max(np.abs(expected))), signal


@settings(max_examples=50, deadline=None)
@given(arrays(float, (7, 10), elements=st.floats(-1e3, 1e3)), st.sampled_from(["four_mass", "multiple_oscillator_n5"]))
def test_outputs_of_rows_are_outputs_of_each_row(states, name):
    """``MassesModel.outputs_of_rows`` (the references' batched outputs) against ``outputs_of`` row by row, at
    arbitrary states: equal to rounding, that is to 1e-13 of the sums of the terms' magnitudes (a signal or an
    energy that cancels to near zero keeps the rounding of its terms)."""
    model = build_monolithic(load_scene(name)).model
    S = states[:, :2 * model.n_dof]
    times = np.arange(len(S)) * 1e-3
    expected = np.array([model.outputs_of(t, s) for t, s in zip(times, S)])
    magnitudes = np.abs(S) @ np.abs(model._G.T)  # the one matrix of the outputs and the energy's quadratic form
    k = len(model.outputs) - 1
    bound = np.column_stack((magnitudes[:, :k], np.sum(magnitudes[:, k:] * np.abs(S), axis=1)))
    assert np.all(np.abs(model.outputs_of_rows(times, S) - expected) <= 1e-13 * (bound + 1e-300))


def test_a_long_analytic_reference_is_the_exact_solution_sample_by_sample():
    """20,000 samples, past the first block (``BLOCK_ROWS``): the blocks' states against ``linear_response``'s, one
    product after another, in every signal to 1e-12 of its range (both the exact map, rounded differently)."""
    scene = load_scene("two_mass_damped", ["manager.duration=20"])
    reference = analytic_reference(scene)
    model = build_monolithic(scene).model
    n = model.n_dof
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n], A[n:, n:] = -np.linalg.solve(model.M, model.K), -np.linalg.solve(model.M, model.C)
    states = linear_response(A, model.initial_state(), scene.manager.macro_step, 20_000)
    outputs = model.outputs_of_rows(np.arange(20_001) * scene.manager.macro_step, states)
    columns = {port.name: j for j, port in enumerate(model.outputs)}
    for signal, values in [*reference.signals.items(), ("energy", reference.energy)]:
        expected = outputs[:, columns[signal] if signal != "energy" else -1]
        assert np.max(np.abs(values - expected)) <= 1e-12 * np.max(np.abs(expected)), signal
