"""The energy-controlled macro-step (manager.step_control = "energy", manager.scheme.energy_step; issue 27).

Its law is libcosim's ECCO: tests/interop/test_ecco.py runs the same OSP file in both and compares every step.
Here: the limits of the law over generated settings, what it does on a decaying transient, the record's time
grid in the summary and the tables, the same digest over Zenoh, the wire's step length, and the scenes refused.
"""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zencosim
from zencosim.manager.wire.protocol import Kind, decode, encode
from zencosim.subsystems.process.endpoint import SubsystemEndpoint

QUANTUM = 1e-4  # [s] manager.macro_step: every macro-step a whole multiple of it
FINE = {"manager.macro_step": QUANTUM, "subsystems.S1.micro_step": QUANTUM, "subsystems.S2.micro_step": QUANTUM,
        "manager.step_control": "energy"}


def energy_scene(duration: float = 0.5, **control) -> zencosim.Scene:
    """two_mass_damped at energy-controlled macro-steps (``control``: [manager.energy_control])."""
    control.setdefault("max_step_size", 0.01)
    overrides = {**FINE, "manager.duration": duration,
                 **{f"manager.energy_control.{key}": value for key, value in control.items()}}
    return zencosim.load_scene("two_mass_damped", overrides)


def steps_of(result) -> np.ndarray:
    """The macro-steps a run took [base steps of QUANTUM]."""
    return np.diff(np.asarray(result.record.point_ticks))


multiples = st.integers(min_value=1, max_value=40)


@settings(max_examples=12, deadline=None)
@given(low=multiples, extra=multiples, first=st.floats(0.0, 1.0), huge=st.booleans())
def test_the_step_stays_within_its_limits_and_reaches_the_one_its_tolerance_asks_for(low, extra, first, huge):
    """A tolerance no residual reaches (1e12 J) takes the step to max_step_size and keeps it there; one every
    residual exceeds (1e-12 J) takes it to min_step_size; never past either."""
    high = low + extra
    start = low + round(first * extra)
    tolerance = 1e12 if huge else 1e-12
    result = zencosim.run(energy_scene(0.3, min_step_size=low * QUANTUM, max_step_size=high * QUANTUM,
                                       step_size=start * QUANTUM, abs_tolerance=tolerance, rel_tolerance=0.0))
    steps = steps_of(result)
    assert steps[:-1].min() >= low and steps.max() <= high  # the last one may be cut to end at the duration
    assert steps[0] == steps[1] == start  # the law first acts after the second step, as libcosim's
    assert steps[-2] == (high if huge else low)
    assert np.asarray(result.record.point_ticks)[-1] * QUANTUM == pytest.approx(0.3)


def test_the_step_shrinks_in_a_transient_and_grows_as_it_decays():
    """Strong damping: from a long first step the law shortens the step while the residual energy is large and
    lengthens it, up to its limit, as the motion dies out; the run ends exactly at its duration."""
    damped = {"subsystems.S1.effects.c1.damping": 5.0, "subsystems.S2.effects.c2.damping": 5.0}
    scene = zencosim.load_scene(energy_scene().path, {**FINE, **damped, "manager.duration": 4.0,
                                                      "manager.energy_control.max_step_size": 0.02,
                                                      "manager.energy_control.step_size": 0.01,
                                                      "manager.energy_control.abs_tolerance": 1e-3})
    result = zencosim.run(scene)
    steps = steps_of(result)
    shortest = int(np.argmin(steps))
    assert steps[shortest] <= steps[0] // 10 and shortest < len(steps) // 4
    assert steps[-2] == 200 and steps.max() == 200  # 0.02 s, max_step_size
    # rates within [0.2, 1.5] of the law's step, which the step taken is truncated from (less than a base step)
    before, after = steps[1:-2], steps[2:-1]
    assert np.all(after >= np.floor(0.2 * before)) and np.all(after <= 1.5 * (before + 1))
    assert result.signal("x2").time[-1] == pytest.approx(4.0, abs=0)
    summary = result.summary
    assert summary["steps"] == len(steps)
    control = summary["step_control"]
    assert control["kind"] == "energy" and control["macro_steps"] == len(steps)
    assert control["min_step"] == pytest.approx(steps.min() * QUANTUM) and control["max_step"] == pytest.approx(0.02)
    assert summary["discrete"] is None  # the exact analysis is of one fixed macro-step


def test_the_step_shortens_as_the_forcing_quickens():
    """two_mass_chirp starts at rest and is forced by a chirp from 1 to 10 Hz: the step starts long (no residual at
    rest: the law keeps its step) and shortens as the forcing's frequency rises, within its limits."""
    fine = {f"subsystems.{name}.micro_step": QUANTUM for name in ("S1", "S2")}
    result = zencosim.run(zencosim.load_scene("two_mass_chirp", {
        **fine, "manager.macro_step": QUANTUM, "manager.step_control": "energy", "manager.energy_control.step_size": 0.01,
        "manager.energy_control.max_step_size": 0.01, "manager.energy_control.abs_tolerance": 1e-5,
        "manager.energy_control.rel_tolerance": 0.0}))
    times = np.asarray(result.record.point_ticks) * QUANTUM
    steps = np.diff(times)
    first, late = steps[times[:-1] < 1.0], steps[(times[:-1] >= 8.0) & (times[:-1] < 9.0)]
    assert steps[0] == pytest.approx(0.01) and first.mean() > 10 * late.mean()  # ~7.8 ms against ~0.37 ms
    assert steps.min() >= QUANTUM * (1 - 1e-9) and steps.max() <= 0.01 * (1 + 1e-9)


def test_a_diverging_run_ends_with_its_verdict_not_an_error():
    """A coupling far too stiff for the step: the residuals overflow to NaN, the law keeps the step, and the run
    completes with its divergence in the summary."""
    scene = zencosim.load_scene("two_mass_damped", {"manager.step_control": "energy", "manager.duration": 10.0,
                                                    "manager.energy_control.max_step_size": 0.002,
                                                    "couplings.c.effects.kc.stiffness": 1e7})
    result = zencosim.run(scene)
    assert result.summary["diverged"] and result.summary["diverged_at_s"] < 10.0
    assert np.asarray(result.record.point_ticks)[-1] == 10_000


def test_the_tables_and_the_nrms_take_each_point_at_its_time(tmp_path):
    """The table's time column is the points' times; the NRMS compares each point with the reference at its
    time: a reference read on the base grid row by row instead would be far off once the steps lengthen."""
    result = zencosim.run(energy_scene(1.0, abs_tolerance=1.0))
    ticks = np.asarray(result.record.point_ticks)
    (path,) = result.write(tmp_path / "out.csv")
    with open(path) as file:
        rows = list(csv.reader(file))
    times = np.array([float(row[0]) for row in rows[1:]])
    assert rows[0][0] == "time [s]" and np.array_equal(times, ticks * round(QUANTUM * 1e9) / 1e9)
    from zencosim.manager.results.reference import analytic_reference
    reference = analytic_reference(result.scene).signals["x2"]
    x2 = result.signal("x2").values
    expected = np.sqrt(np.mean((x2 - reference[ticks]) ** 2)) / (reference[ticks].max() - reference[ticks].min())
    assert result.summary["signals"]["x2"]["nrms"] == pytest.approx(expected, rel=1e-12)
    assert result.summary["signals"]["x2"]["nrms"] < 0.02


@pytest.mark.parametrize("scene, order", [("two_mass_damped", 0), ("two_mass_damped", 1), ("two_mass_damped", 2),
                                          ("mass_chain", 1), ("coupled_pendula", 2)])
def test_at_a_step_that_never_changes_it_is_the_fixed_step_jacobi_run(scene, order):
    """min_step_size = step_size = max_step_size = 5 macro-steps: the same input polynomials (ZOH, FOH, SOH through
    the points at their times) and the same outputs as ``manager.scheme.jacobi`` at that macro-step, bit for bit."""
    base = zencosim.load_scene(scene)
    step = base.manager.macro_step
    fine = {f"subsystems.{name}.micro_step": step / 5 for name in base.subsystems}
    fixed = zencosim.run(zencosim.load_scene(scene, {**fine, "manager.extrapolation": order,
                                                      "manager.duration": 100 * step}))
    energy = zencosim.run(zencosim.load_scene(scene, {
        **fine, "manager.extrapolation": order, "manager.duration": 100 * step, "manager.macro_step": step / 5,
        "manager.step_control": "energy", **{f"manager.energy_control.{key}": step for key in
                                             ("step_size", "min_step_size", "max_step_size")}}))
    assert np.array_equal(np.asarray(energy.record.point_ticks), np.arange(101) * 5)
    assert energy.digest == fixed.digest
    for name in fixed.signals:
        assert np.array_equal(energy.signal(name).values, fixed.signal(name).values, equal_nan=True), name


def test_multi_rate_at_a_step_that_never_changes_it_is_the_fixed_step_jacobi_run():
    """hydraulic_crane (the arm every 40 base steps, the cylinder's FOH inputs): the law sets the period, the points
    keep the rate ratio; at a constant step every output and residual is the Jacobi run's, bit for bit."""
    step = zencosim.load_scene("hydraulic_crane").manager.macro_step
    fixed = zencosim.run(zencosim.load_scene("hydraulic_crane", {"manager.duration": 0.5}))
    energy = zencosim.run(zencosim.load_scene("hydraulic_crane", {
        "manager.duration": 0.5, "manager.step_control": "energy",
        **{f"manager.energy_control.{key}": step for key in ("step_size", "min_step_size", "max_step_size")}}))
    assert np.array_equal(np.asarray(energy.record.point_ticks), np.arange(2001))
    assert energy.digest == fixed.digest
    for name in fixed.signals:
        assert np.array_equal(energy.signal(name).time, fixed.signal(name).time), name
        assert np.array_equal(energy.signal(name).values, fixed.signal(name).values, equal_nan=True), name


def test_multi_rate_the_law_sets_the_period_and_keeps_the_ratio(tmp_path):
    """The arm steps once per period (40 points), the cylinder at every point; points are evenly spaced within a
    period; the tables, a recording's re-run and its export agree."""
    from zencosim.recordings.reader import read_recording
    from zencosim.recordings.verify import verify

    scene = zencosim.load_scene("hydraulic_crane", {"manager.duration": 1.0, "manager.step_control": "energy",
                                                    "manager.energy_control.max_step_size": 0.001,
                                                    "manager.energy_control.abs_tolerance": 10.0})
    result = zencosim.run(scene, record=tmp_path / "crane.mcap")
    ticks = np.asarray(result.record.point_ticks)
    spacing = np.diff(ticks).reshape(-1, 40)
    assert np.all(spacing == spacing[:, :1]) and len(np.unique(spacing[:, 0])) > 2
    assert np.array_equal(result.signal("s").time, ticks[::40] * 250_000 / 1e9)  # the arm's position: per period
    assert np.array_equal(result.signal("f").time, ticks * 250_000 / 1e9)  # the cylinder's force: every point
    assert result.digest == zencosim.run(scene).digest  # messages (recorded) and direct calls
    assert verify(read_recording(tmp_path / "crane.mcap")).passed
    recorded = zencosim.load_recording(tmp_path / "crane.mcap")
    for name in result.signals:
        assert np.array_equal(recorded.signal(name).time, result.signal(name).time), name
        assert np.array_equal(recorded.signal(name).values, result.signal(name).values, equal_nan=True), name


def test_a_recorded_run_verifies_and_reads_back_as_it_ran(tmp_path):
    """The recording's re-run takes the same steps (verify: every message bit for bit, up to its last status), and
    its signals are the run's at the same times; the recorded run (messages) is the unrecorded one (direct calls)."""
    from zencosim.recordings.reader import read_recording
    from zencosim.recordings.verify import verify

    path = tmp_path / "energy.mcap"
    scene = energy_scene(0.3, abs_tolerance=1.0)
    result = zencosim.run(scene, record=path)  # through the messages; unrecorded, the scheme calls the subsystems
    assert len(set(steps_of(result))) > 3 and result.digest == zencosim.run(scene).digest
    checked = verify(read_recording(path))
    assert checked.passed and checked.last_step == round(0.3 / QUANTUM)
    recorded = zencosim.load_recording(path)
    for name in ("x2", "fc", "delta_p.c", "delta_e.c"):
        assert np.array_equal(recorded.signal(name).time, result.signal(name).time), name
        assert np.array_equal(recorded.signal(name).values, result.signal(name).values), name


@pytest.mark.slow
@pytest.mark.multiprocess
def test_over_zenoh_the_run_is_the_in_process_one():
    """Every process follows every bond, so the steps — and the digest — are the same (FOH inputs: polynomials
    through points at varying spacing on the wire, the default abs_tolerance from the energy at t_0 that every
    process reads from its own replica; and the multi-rate crane)."""
    scene = zencosim.load_scene(energy_scene(0.3, abs_tolerance=1.0).path, {
        **FINE, "manager.duration": 0.3, "manager.extrapolation": 1, "manager.energy_control.max_step_size": 0.01})
    crane = zencosim.load_scene("hydraulic_crane", {"manager.duration": 0.2, "manager.step_control": "energy",
                                                    "manager.energy_control.max_step_size": 0.001,
                                                    "manager.energy_control.abs_tolerance": 10.0})  # multi-rate
    for run in (scene, crane):
        inproc, zenoh = zencosim.run(run), zencosim.run(run, bus="zenoh")
        assert zenoh.digest == inproc.digest
        assert np.array_equal(np.asarray(zenoh.record.point_ticks), np.asarray(inproc.record.point_ticks))
        assert len(set(steps_of(inproc))) > 3  # the steps did vary


def test_a_step_command_carries_its_length_in_base_steps():
    """ref of a STEP: its length in base steps (0: the communication step); the reply's step and time follow it,
    on the zero-order fast path (one row) and through the decoded path (a second row, of zeros) alike."""
    from zencosim.manager.assembly import plan_scene

    scene = energy_scene()
    plan, _ = plan_scene(scene)
    s2, base = plan.by_name("S2"), plan.base_step_ns

    def reply(rows: int, span: int) -> tuple:
        endpoint = SubsystemEndpoint(plan_scene(scene)[1]["S2"], s2.ratio, base)  # a fresh subsystem at t = 0
        values = np.zeros((rows, len(s2.inputs)))
        values[0] = 1.0
        message = decode(endpoint.handle(encode(Kind.STEP, 0, 0, values, rows, ref=span)), "S2")
        return message.kind, message.step, message.time_ns, message.values.tolist()

    assert reply(1, 7)[:3] == (Kind.OUTPUT, 7, 7 * base)
    assert reply(1, 0)[:3] == (Kind.OUTPUT, 1, base)
    assert reply(2, 7) == reply(1, 7)
    assert reply(1, 7)[3] != reply(1, 0)[3]


@pytest.mark.parametrize("overrides, key, reason", [
    ({"manager.scheme": "gauss-seidel"}, "manager.scheme", "expected 'jacobi' with manager.step_control = 'energy'"),
    ({"manager.correction.enabled": True}, "manager.correction", "energy correction is derived for a fixed"),
    ({"manager.compensation": "eigenstructure"}, "manager.compensation", "expected 'none'"),
    ({"manager.realtime": True}, "manager.realtime", "real time paces a fixed macro-step"),
    ({"manager.energy_control.max_step_size": 0.00105}, "manager.energy_control.max_step_size",
     "expected a whole multiple of manager.macro_step"),
    ({"manager.energy_control.step_size": 0.02}, "manager.energy_control",
     "expected min_step_size <= step_size <= max_step_size"),
    ({"manager.energy_control.min_change_rate": 2.0}, "manager.energy_control", "expected min_change_rate <="),
])
def test_what_the_energy_controlled_step_does_not_run_is_refused_by_name(overrides, key, reason):
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene("two_mass_damped", {**FINE, "manager.energy_control.max_step_size": 0.01, **overrides})
    found = {p.key: p.reason for p in caught.value.problems}
    assert key in found and reason in found[key], found


def test_the_energy_control_table_waits_unused_at_a_fixed_step():
    fixed = zencosim.load_scene("two_mass_damped", {"manager.energy_control.max_step_size": 0.01})
    assert fixed.manager.step_control == "fixed" and zencosim.run(fixed).summary["step_control"] is None


def test_the_readme_example_adapts_its_step_at_the_defaults(tmp_path):
    """The README's ``zencosim run two_mass_damped --set manager.step_control=energy``: defaults drawn
    from the scene — the macro-step (1 ms) as the first and smallest step, 20 of it as the largest, abs_tolerance
    1e-3 of the energy at t_0 (10,000 J: 10 J) — and the step varies, at no bound for most of the run, the NRMS of
    x2 within 3x that of the fixed 1 ms step (ZOH's error grows with the step)."""
    summary_path = tmp_path / "summary.json"
    done = subprocess.run([sys.executable, "-m", "zencosim", "run", "two_mass_damped", "--set",
                           "manager.step_control=energy", "--summary", str(summary_path)],
                          capture_output=True, text=True, timeout=300, env={**os.environ, "COLUMNS": "1000"})
    assert done.returncode == 0, done.stderr
    summary = json.loads(summary_path.read_text())
    control = summary["step_control"]
    parameters = control["parameters"]
    assert (parameters["min_step_size"], parameters["step_size"], parameters["max_step_size"]) == (0.001, 0.001, 0.02)
    assert parameters["abs_tolerance"] == pytest.approx(1e-3 * summary["energy"]["initial"]) == pytest.approx(10.0)
    assert control["min_step"] == 0.001 and control["max_step"] >= 0.005  # it varies
    assert control["macro_steps"] < 0.8 * 10_000 and control["at_limit"] is None and "macro-step at a bound" not in done.stdout
    fixed = zencosim.run(zencosim.load_scene("two_mass_damped")).summary
    assert summary["signals"]["x2"]["nrms"] < 3.0 * fixed["signals"]["x2"]["nrms"]


@pytest.mark.parametrize("control, bound, share_key", [
    ({"abs_tolerance": 0.1}, "min_step_size", "time_at_min_step"),  # tighter than any step's residual energy
    ({"abs_tolerance": 1e12, "max_step_size": 0.002}, "max_step_size", "time_at_max_step"),  # looser than any
])
def test_a_step_that_sat_at_a_bound_most_of_the_run_is_reported(control, bound, share_key):
    scene = zencosim.load_scene("two_mass_damped", {"manager.step_control": "energy", "manager.duration": 1.0,
                                                    **{f"manager.energy_control.{k}": v for k, v in control.items()}})
    result = zencosim.run(scene)
    steps = steps_of(result) * result.record.plan.base_step_ns * 1e-9  # [s]
    summary = result.summary["step_control"]
    limit = summary["parameters"][bound]
    at = steps[np.isclose(steps, limit)] if bound == "max_step_size" else steps[steps <= limit * (1 + 1e-12)]
    assert summary["at_limit"] == bound and summary[share_key] == pytest.approx(at.sum() / steps.sum())
    assert summary[share_key] > 0.5


def test_a_study_varies_the_step_control_like_any_other_key(tmp_path):
    """``--vary manager.step_control=fixed,energy``: the energy-controlled point counts the steps it took and has
    no predicted verdict (the exact analysis is of one fixed step)."""
    from zencosim.manager.study.grid import merge_axes, parse_axis
    from zencosim.manager.study.study import StudyOptions, run_study

    scene = zencosim.load_scene("two_mass_damped", {"manager.duration": 1.0, "manager.energy_control.max_step_size": 0.01,
                                                    "manager.energy_control.abs_tolerance": 1.0})
    axes = merge_axes([parse_axis("manager.macro_step=1e-3"), parse_axis("manager.step_control=fixed,energy")])
    study = run_study(scene, axes, StudyOptions(repeats=1, zenoh="none"), str(tmp_path))
    points = {p["values"]["manager.step_control"]: p for p in study["points"]}
    assert points["fixed"]["steps"] == 1000 and points["fixed"]["stable_predicted"] is True
    assert 100 < points["energy"]["steps"] < 1000 and points["energy"]["stable_predicted"] is None
    assert points["energy"]["nrms"]["x2"] is not None


def test_a_scene_without_a_power_bond_has_nothing_to_control_the_step_by(tmp_path):
    text = Path(energy_scene().path).read_text()
    text = text[:text.index("[couplings.c]")].replace('signals = ["x2", "fc"]', "signals = []")
    path = tmp_path / "free.toml"
    path.write_text(text)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(path, {**FINE, "manager.energy_control.max_step_size": 0.01})
    assert {p.key: p.reason for p in caught.value.problems}["manager.step_control"].endswith("this scene has none")


def zencosim_command(command: str, *options: str, control: str = "energy") -> subprocess.CompletedProcess:
    """``zencosim COMMAND two_mass_damped OPTIONS`` with ``manager.step_control = control`` and a maximum step, run as
    a user runs it."""
    return subprocess.run([sys.executable, "-m", "zencosim", command, "two_mass_damped", *options,
                           "--set", f"manager.step_control={control}", "--set", "manager.energy_control.max_step_size=0.01"],
                          capture_output=True, text=True, timeout=120)


def test_the_command_line_refuses_real_time_with_a_varying_step():
    result = zencosim_command("run", "--realtime")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "--realtime paces a fixed macro-step; manager.step_control = 'energy' varies it" in result.stderr


def test_analyze_says_which_fixed_step_it_analyses():
    result = zencosim_command("analyze")
    assert result.returncode == 0, result.stderr
    assert ("this is the scheme at a fixed macro-step of 0.001 s; the run varies it up to 0.01 s"
            in " ".join(result.stderr.split()))


@pytest.mark.parametrize("control, said", [("energy", "energy-controlled macro-steps of 0.001 … 0.01 s"),
                                           ("fixed", "10000 macro-steps of 0.001 s")])
def test_check_says_which_steps_the_scene_takes(control, said):
    """An [manager.energy_control] table at a fixed step is not used, and `zencosim check` does not say it is."""
    result = zencosim_command("check", control=control)
    assert result.returncode == 0, result.stderr
    assert said in result.stdout


# The controller's parameters: bounded at load, so that the law never overflows at run time ----------------------

CONTROL_PARAMETERS = ("safety_factor", "min_change_rate", "max_change_rate", "abs_tolerance", "rel_tolerance",
                      "p_gain", "i_gain")
any_float = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [0.0, 5e-324, 1e-300, 1e-3, 0.1, 0.5, 0.9, 1.0, 1e3, 1e30, 2.0**63, 1e308])
residual = st.sampled_from([0.0, 5e-324, 1e-300, 1e-12, 1.0, 1e12, 1e300, np.inf, np.nan]) | st.floats()


@settings(max_examples=60, deadline=None)
@given(changed=st.dictionaries(st.sampled_from(CONTROL_PARAMETERS), any_float, min_size=1, max_size=3),
       powers=st.lists(st.lists(residual, min_size=2, max_size=2), min_size=3, max_size=6))
def test_a_controller_accepted_at_load_never_fails_in_its_law(changed, powers):
    """Any value of any parameter is refused by key or gives a law that sets a step within its limits whatever the
    bonds' residual powers (0, the smallest float, 1e300, inf, NaN): p_gain = 1e308 raised an OverflowError at run
    time, tolerances both 0 a ZeroDivisionError."""
    from zencosim.manager.scene.settings import EnergyControlSettings
    from zencosim.manager.scheme.energy_step import StepLaw
    from zencosim.subsystems.params import Problems, read_table

    problems = Problems()
    control = read_table(EnergyControlSettings, {"max_step_size": 0.01, **changed}, "manager.energy_control", problems)
    if control is None:
        assert problems and all(p.key.startswith("manager.energy_control.") for p in problems)
        gains = {"p_gain"} if {"p_gain", "i_gain"} & set(changed) else set()  # their sum is named by p_gain
        assert {p.key.rsplit(".", 1)[1] for p in problems} <= set(changed) | gains
        return
    law = StepLaw(control, base_step_ns=100_000)
    start_ns = 0
    for power in powers:
        taken = law.step_ns
        law.adjust(power, start_ns, taken)
        start_ns += taken
        assert law.min_ns <= law.step_ns <= law.max_ns


@pytest.mark.parametrize("parameter, value, reason", [
    ("p_gain", "1e308", "expected a number >= 0.0 and <= 1.0, got 1e+308"),
    ("p_gain", str(2**63), f"expected a number >= 0.0 and <= 1.0, got {2**63}"),
    ("i_gain", "1e30", "expected a number >= 0.0 and <= 1.0, got 1e+30"),
    ("safety_factor", "5e-324", "expected a number >= 0.1 and <= 1.0, got 5e-324"),
    ("abs_tolerance", "0.0", "expected a number > 0.0 [J], got 0.0"),
    ("max_change_rate", "1e308", "expected a number >= 0.001 and <= 1000.0, got 1e+308"),
])
def test_an_energy_control_parameter_out_of_its_range_is_one_line_and_exit_2(parameter, value, reason):
    """What ``check`` accepted and a run then failed on (an OverflowError in the law): refused at load, by key."""
    import contextlib
    import io

    from zencosim.cli.main import main
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        status = main(["check", "two_mass_damped", "--set", "manager.step_control=energy",
                       "--set", "manager.energy_control.max_step_size=0.01",
                       "--set", f"manager.energy_control.{parameter}={value}"])
    assert status == 2 and "Traceback" not in errors.getvalue()
    assert f"manager.energy_control.{parameter}: {reason}" in " ".join(errors.getvalue().split())


def test_the_corners_of_the_accepted_ranges_never_fail_in_the_law():
    """Every corner of the bounds (gains summing to 1, safety 0.1 and 1, change rates 1e-3 and 1e3, tolerances
    5e-324 and 1e300 J, 0 and 1) against residual powers from the smallest float to 1e300, inf, and the one that
    makes the error ε its smallest positive value (2.3e142 W over 0.1 ms against 1e300 J: ε = 2.3e-162, which a
    gain sum of 2 would raise to 1.9e323, beyond a float): the step stays within its limits."""
    import itertools

    from zencosim.manager.scene.settings import EnergyControlSettings
    from zencosim.manager.scheme.energy_step import StepLaw

    sequences = ([5e-324, 5e-324, 1e300], [1e300, 5e-324, 0.0], [2.3e142, 2.3e142, 5e-324], [np.inf, np.inf, 1.0],
                 [1e-300, 1e300, np.inf])
    rates = [(1e-3, 1e-3), (1e-3, 1e3), (1e3, 1e3)]
    for (p, i), safety, (low, high), absolute, relative in itertools.product(
            [(1.0, 0.0), (0.0, 1.0), (0.5, 0.5)], [0.1, 1.0], rates, [5e-324, 1e300], [0.0, 1.0]):
        control = EnergyControlSettings(max_step_size=0.01, p_gain=p, i_gain=i, safety_factor=safety,
                                        min_change_rate=low, max_change_rate=high, abs_tolerance=absolute,
                                        rel_tolerance=relative)
        for powers in sequences:
            law, start_ns = StepLaw(control, base_step_ns=100_000), 0  # its first step: 0.1 ms
            for power in powers:
                taken = law.step_ns
                law.adjust([power, power], start_ns, taken)
                start_ns += taken
                assert law.min_ns <= law.step_ns <= law.max_ns
