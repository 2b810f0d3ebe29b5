"""A study without an analytic reference: the reference extrapolated from the grid's own finest
points (Richardson), checked on expansions whose limit is known, against the summary's NRMS, and on
two_mass_damped_fmu against the analytic NRMS of the built-in two_mass_damped; its report, whatever there is to
plot."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.manager.test_cli import zencosim
from tests.manager.test_study import documented_keys, leaf_paths, study_of
from zencosim.manager.results.summary import nrms
from zencosim.manager.run import references
from zencosim.manager.scene.load import load_scene
from zencosim.manager.study.extrapolation import (Extrapolated, Samples, extrapolate, nrms_against, observed_order,
                                                  zero_step_weights)
from zencosim.manager.study.measure import measure_point
from zencosim.manager.study.report import FILES, write_report

DURATION_NS = 1_000_000_000
STEP_FACTORS = [(1, 2, 4, 8), (1, 2, 6, 12), (1, 3, 6, 18)]  # coarser steps, whole multiples of the finer ones


def exact(t: np.ndarray) -> np.ndarray:
    return np.sin(2 * np.pi * t) + 0.3 * np.cos(5 * t)


def term(k: int, coefficient: float, t: np.ndarray) -> np.ndarray:
    """A smooth error term c_k(t) of the expansion."""
    return coefficient * np.sin((k + 1) * t + k)


def run_of(step_ns: int, coefficients: list[float]) -> Samples:
    """y_h(t) = y(t) + Σ_k c_k(t) h^k at t = 0, h, 2h, …, 1 s."""
    t_ns = np.arange(0, DURATION_NS + 1, step_ns, dtype=np.int64)
    t, h = t_ns * 1e-9, step_ns * 1e-9
    return Samples(t_ns, exact(t) + sum(term(k, c, t) * h ** k for k, c in enumerate(coefficients, 1)))


@settings(max_examples=50, deadline=None)  # no wall-clock deadline: the machine may be loaded
@given(st.integers(1_000_000, 4_000_000), st.sampled_from(STEP_FACTORS), st.integers(3, 4),
       st.lists(st.floats(-50.0, 50.0), min_size=4, max_size=4))
def test_the_extrapolation_cancels_every_term_below_h_to_the_m(fine_ns, factors, m, coefficients):
    """m points of y_h = y + c_1 h + … + c_m h^m: T_m is y + c_m Σ w_i h_i^m exactly (the Lagrange weights at h = 0
    cancel h^1 … h^(m-1)), at the samples the points share (to rounding); on the finest point's other samples the
    correction T_m - y_1 is a cubic spline through the shared ones, within H^4 max|f^(4)| / 24 (H the coarsest step):
    the size of a cubic's interpolation error (Hall and Meyer's bound for a clamped spline, 5/384 H^4 max|f^(4)|, is
    a third of it; the not-a-knot ends used here exceed that: generated cases reach 0.027 H^4 max|f^(4)|)."""
    steps_ns = [fine_ns * f for f in factors[:m]]
    coefficients = coefficients[:m]
    runs = [run_of(h_ns, coefficients) for h_ns in steps_ns]
    steps = [h_ns * 1e-9 for h_ns in steps_ns]
    result = extrapolate(steps, runs)
    assert isinstance(result, Extrapolated)
    left = float(zero_step_weights(steps) @ np.array([h ** m for h in steps]))  # the h^m term T_m keeps
    t = result.reference.times_ns * 1e-9
    expected = exact(t) + left * term(m, coefficients[-1], t)
    shared = np.isin(result.reference.times_ns, runs[-1].times_ns)
    deviation = np.abs(result.reference.values - expected)
    assert np.max(deviation[shared]) <= 1e-12
    fourth_derivative = (sum(abs(c) * (k + 1) ** 4 * steps[0] ** k for k, c in enumerate(coefficients, 1))
                         + abs(left * coefficients[-1]) * (m + 1) ** 4)  # of the correction: terms sin((k+1) t + k)
    assert np.max(deviation) <= steps[-1] ** 4 * fourth_derivative / 24 + 1e-12
    assert result.macro_steps == tuple(steps)  # on the finest samples up to the coarsest's last (shorter: 18 ms)
    assert np.array_equal(result.reference.times_ns, runs[0].times_ns[runs[0].times_ns <= runs[-1].times_ns[-1]])


def test_a_polynomial_of_degree_m_minus_1_is_extrapolated_exactly_and_its_bar_is_the_lower_order_one():
    """Without an h^m term T_m is the limit itself (to rounding), and the bar is T_(m-1)'s error: the h^(m-1) term
    that the finest m - 1 points cannot cancel: T_2 = 2 y_1 - y_2 keeps c_2 (2 h_1^2 - h_2^2), for steps 1, 2, 4 ms."""
    steps_ns = [1_000_000, 2_000_000, 4_000_000]
    runs = [run_of(h_ns, [3.0, 7.0]) for h_ns in steps_ns]
    result = extrapolate([h * 1e-9 for h in steps_ns], runs)
    t = result.reference.times_ns * 1e-9
    assert np.max(np.abs(result.reference.values - exact(t))) < 1e-12
    shared = runs[-1].times_ns * 1e-9
    left = 2 * 1e-3 ** 2 - 2e-3 ** 2  # -2e-6
    lower_error = left * term(2, 7.0, shared)
    assert result.bar_rms == pytest.approx(float(np.sqrt(np.mean(lower_error ** 2))), rel=1e-6)
    assert result.bar_max == pytest.approx(float(np.max(np.abs(lower_error))), rel=1e-6)


@settings(deadline=None)
@given(st.floats(0.3, 4.0), st.floats(1e-4, 1e-2), st.floats(1.2, 4.0), st.floats(1.2, 4.0))
def test_the_observed_order_of_a_pure_power_is_that_power(p, h1, ratio_2, ratio_3):
    """y_h = y + c h^p at any three steps: the observed order is p (bisection to the float's resolution)."""
    steps = [h1, h1 * ratio_2, h1 * ratio_2 * ratio_3]
    t = np.linspace(0.0, 1.0, 50)
    values = [term(1, 2.0, t) * h ** p for h in steps]  # the limit left out: it cancels, adding only rounding
    assert observed_order(steps, values) == pytest.approx(p, rel=1e-9)


def test_differences_that_do_not_shrink_with_the_step_have_no_order():
    t = np.linspace(0.0, 1.0, 50)
    values = [exact(t) + term(1, 1.0, t) * e for e in (0.0, 1.0, 1.5)]  # the finer difference is the larger
    assert observed_order([1e-3, 2e-3, 4e-3], values) is None
    assert observed_order([1e-3, 2e-3, 4e-3], [exact(t)] * 3) is None


def test_an_exact_reference_gives_the_summary_nrms_at_the_runs_own_samples():
    """Bars zero: the NRMS is the summary's (paper 000 Eq. 42), at a coarser run's samples (a subset of the
    reference's) exactly; at samples between the reference's (a 1.5 ms run against a 1 ms reference) through the
    cubic spline, to 1e-8 of the NRMS."""
    reference = run_of(1_000_000, [])
    exact_reference = Extrapolated(reference, (1e-3, 2e-3, 4e-3), 1.0, 0.0, 0.0)
    for step_ns, tolerance in ((2_000_000, 1e-14), (1_500_000, 1e-8)):
        run = run_of(step_ns, [0.4, -3.0])
        estimate, bar = nrms_against(exact_reference, run)
        assert estimate == pytest.approx(nrms(run.values, exact(run.times_ns * 1e-9)), rel=tolerance)
        assert bar == pytest.approx(0.0, abs=1e-15)


@settings(deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.floats(1e-4, 0.2), st.floats(0.0, 0.5))
def test_the_error_bar_holds_the_nrms_against_the_exact_solution(seed, size, run_error):
    """A reference off the exact solution by δ, told rms(δ) and max|δ| at the run's samples: the run's NRMS against
    the exact solution lies within the bar of its NRMS against the reference (triangle inequality, span)."""
    rng = np.random.default_rng(seed)
    run = run_of(2_000_000, [])
    t = run.times_ns * 1e-9
    run = Samples(run.times_ns, run.values + run_error * rng.standard_normal(len(t)))
    delta = size * rng.standard_normal(len(t)) * rng.uniform(0.0, 1.0, len(t))
    reference = Extrapolated(Samples(run.times_ns, exact(t) + delta), (1e-3, 2e-3, 4e-3), None,
                             float(np.sqrt(np.mean(delta ** 2))), float(np.max(np.abs(delta))))
    estimate, bar = nrms_against(reference, run)
    assert abs(nrms(run.values, exact(t)) - estimate) <= bar * (1 + 1e-12)


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_study_of_the_fmu_scene_without_reference_gives_the_analytic_nrms_within_each_bar(examples, tmp_path):
    """Issue 41's target: two_mass_damped_fmu (reference "none") studied from the command line extrapolates its
    reference; every NRMS estimate lies within its error bar of the analytic NRMS of the built-in two_mass_damped
    at the same point (the same system: the FMUs agree with it to 1e-13 of x2's range), and the bars resolve the
    errors (under a tenth of ZOH's; under FOH's own, which is 15 times smaller). Its report is written, states
    the reference, and has only documented keys; run again, it measures nothing and says the same. 1 s of simulated
    time keeps it to a few seconds."""
    report = tmp_path / "report"

    def study_run() -> tuple[dict, str]:
        result = zencosim("study", str(examples / "two_mass_damped_fmu.toml"), "--set", "manager.duration=1",
                          "--vary", "manager.macro_step=0.5e-3,1e-3,2e-3", "--vary", "manager.extrapolation=0,1",
                          "--repeats", "1", "--zenoh", "none", "--cache", str(tmp_path / "cache"), "--out", str(report))
        assert result.returncode == 0, result.stderr
        return json.loads((report / "study.json").read_text()), result.stdout

    study, stdout = study_run()
    again, _ = study_run()  # from the cache, the points' signals kept beside them: nothing runs, the same estimates
    assert (again["run"]["ran"], again["run"]["cached"]) == (0, 6)
    estimates = [[(p["error"], p["error_bar"]) for p in s["points"]] for s in (study, again)]
    assert estimates[0] == estimates[1]
    assert study["reference"] == "extrapolated"
    described = study["extrapolation"]["x2"]
    assert described["reason"] is None and len(described["macro_steps"]) == 3 and 0.9 < described["order"] < 2.1
    assert len(study["points"]) == 6
    for point in study["points"]:
        analytic = measure_point("two_mass_damped", tuple(point["overrides"]), 1)["nrms"]["x2"]
        assert point["stable"] and abs(point["error"] - analytic) <= point["error_bar"], point["overrides"]
        zoh = point["values"]["manager.extrapolation"] == 0
        assert point["error_bar"] < (0.1 if zoh else 1.0) * analytic
    text = (report / "study.md").read_text()
    assert "extrapolated to a zero macro-step from ZOH at 0.5, 1, 2 ms (Richardson" in text
    assert "| ≤ 1 %" in stdout and "±" in stdout
    assert all((report / name).stat().st_size > 0 for name in FILES)
    documented = documented_keys()
    prefixes = {d[:i] for d in documented for i, c in enumerate(d) if c in ".["}
    found = leaf_paths(study, documented)
    assert {f for f in found if f not in documented and f not in prefixes} == set()
    assert {d for d in documented if d.startswith("extrapolation.")} <= found


@pytest.mark.slow
@pytest.mark.multiprocess
def test_the_report_is_written_whatever_there_is_to_plot(tmp_path):
    """Issue 41: a study without an analytic reference ended in a traceback ("Data cannot be log-scaled because all
    values are <= 0"). Two points per method: no extrapolation (its reason is stated) and no error; then every error
    zero; then no point at all: each time the report's files are written, and the plots say what they lack."""
    study = study_of("two_mass_damped", ["manager.duration=0.05", "outputs.reference=extrapolated"],
                     ["manager.macro_step=1e-3,2e-3"], tmp_path / "cache")
    assert study["extrapolation"]["x2"]["reason"].startswith("no method has 3 stable points whose samples nest")
    assert all(p["error"] is None for p in study["points"]) and study["answers"][0]["point"] is None
    zero = copy.deepcopy(study)
    for point in zero["points"]:
        point["error"], point["nrms"] = 0.0, dict.fromkeys(point["nrms"], 0.0)
    empty = {**copy.deepcopy(study), "points": [], "methods": []}
    for variant, case in (("two points", study), ("errors zero", zero), ("no point", empty)):
        folder = tmp_path / variant.replace(" ", "_")
        folder.mkdir()
        written = write_report(case, folder)
        assert [p.name for p in written] == list(FILES), variant
        assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in written if p.suffix == ".png"), variant
        assert "none: the reference could not be extrapolated (no method has 3" in (folder / "study.md").read_text()


def test_a_single_run_of_a_scene_whose_reference_is_extrapolated_says_it_has_none():
    """``outputs.reference = "extrapolated"`` is a study's (several macro-steps); a run measures no NRMS and says why."""
    refs, note = references(load_scene("two_mass_damped", ["outputs.reference=extrapolated"]))
    assert refs == {} and note.startswith("no reference: 'extrapolated' is extrapolated by `zencosim study`")
