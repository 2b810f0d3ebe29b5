"""The solve_ivp reference: the subsystems integrated together with their couplings resolved exactly.
It reproduces the matrix-exponential solution of a linear scene, and its own error on the nonlinear
scenes is far below the co-simulation errors it measures."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from zencosim.manager.results.reference import (
    CoupledSystem,
    _ticks_reached,
    analytic_reference,
    solve_ivp_reference,
)
from zencosim.manager.scene.load import load_scene


@pytest.mark.parametrize("scene_name", ["two_mass_damped", "multiple_oscillator_n3"])
def test_matches_the_analytic_solution_of_a_linear_scene(scene_name):
    # LSODA at rtol 1e-10: we measure 6e-10 of the range of every signal and 2e-9 of E0
    scene = load_scene(scene_name, ["manager.duration=2.0"])
    integrated, exact = solve_ivp_reference(scene), analytic_reference(scene)
    for name, signal in exact.signals.items():
        assert np.max(np.abs(integrated.signals[name] - signal)) < 1e-8 * np.ptp(signal), name
    assert np.max(np.abs(integrated.energy - exact.energy)) < 1e-8 * exact.energy[0]


@pytest.mark.parametrize("scene_name,duration", [("coupled_pendula", 5.0), ("nonlinear_oscillator_case2", 1.0),
                                                 ("hydraulic_crane", 2.0)])
def test_own_error_against_a_hundred_times_tighter_run(scene_name, duration):
    # we measure (10 s): pendula 1.4e-8, case 2 2e-9, crane 2e-7 of the range of a signal; the sqrt springs of
    # nonlinear_oscillator_case1 (not Lipschitz at zero elongation) 4.6e-6, not run here (17 s)
    scene = load_scene(scene_name, [f"manager.duration={duration}"])
    coarse, fine = solve_ivp_reference(scene), solve_ivp_reference(scene, rtol=1e-12, atol=1e-12)
    for name, signal in fine.signals.items():
        assert np.max(np.abs(coarse.signals[name] - signal)) < 1e-6 * np.ptp(signal), name


@given(st.integers(1, 10**12), st.integers(0, 10**6), st.integers(0, 10), st.integers(-3, 3), st.floats(0.0, 1.0))
@example(1, 3, 0, -1, 0.0)  # 3 ns less an ulp: t / step rounds up to 3.0, a tick not reached
@example(1, 31, 0, 0, 0.0)  # 31 ns: t / step rounds down below 31, a tick reached
def test_the_ticks_a_solver_step_reaches_are_those_searchsorted_finds_on_the_grid(step_ns, tick, beyond, ulps, share):
    """How many ticks ``k × step`` lie at or before a solver's time ``t``: as ``np.searchsorted(np.arange(n_ticks + 1)
    * step, t, "right")`` finds (``solve_ivp``'s ``t_eval``), for a time a few units of the last place off a tick
    (where ``t / step`` rounds across an integer, both ways) and between two ticks."""
    step, n_ticks = step_ns * 1e-9, tick + beyond
    t = tick * step
    for _ in range(abs(ulps)):
        t = float(np.nextafter(t, np.inf if ulps > 0 else 0.0))
    grid = np.arange(n_ticks + 1) * step
    for time in (t, (tick + share) * step):
        assert _ticks_reached(time, step, n_ticks) == int(np.searchsorted(grid, time, "right")), time


@pytest.mark.parametrize("scene_name", ["hydraulic_crane", "double_pendulum", "constrained_two_mass", "coupled_pendula",
                                        "nonlinear_oscillator_case1"])
def test_the_outputs_are_every_model_evaluated_with_its_exact_inputs(scene_name):
    """``CoupledSystem.outputs`` keeps the outputs the initialisation order evaluated with the final inputs instead
    of evaluating them again: bit for bit what every model gives with its exact inputs (``resolve``), at states
    along the scene's reference trajectory shaken by seeded noise (a joint's force changes its sides' inputs after
    they were asked: those are evaluated again)."""
    system = CoupledSystem(load_scene(scene_name))
    rng = np.random.default_rng(7)
    for t in (0.0, 0.013, 0.5):
        Z = system.z0 * (1.0 + 0.1 * rng.standard_normal(system.z0.shape)) + 0.01 * rng.standard_normal(system.z0.shape)
        inputs = system.resolve(t, Z)
        expected = [m.outputs_at(t, Z[sl], w) for m, sl, w in zip(system.models, system.slices, inputs)]
        assert [y.tobytes() for y in system.outputs(t, Z)] == [y.tobytes() for y in expected]
