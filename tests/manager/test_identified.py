"""Identified subsystems in the exact discrete analysis (``manager.analysis.identified``).

The oracle is the built-in model of the same system: its one-step map is composed exactly from its matrices
(``manager.analysis.discrete.subsystem_map``), the identified one is realised from the responses of the FMU or
Python model alone. Tolerances: identification by ERA is exact for a linear subsystem up to the rounding of the
probes' differences, so 1e-8 leaves orders to spare; the largest stable step is bisected to 1e-4 relative on both
sides, so 1e-3 holds it to 0.1 %.
"""
from __future__ import annotations

import json
from importlib import resources

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zencosim
from zencosim.cli.main import main
from zencosim.manager.analysis.discrete import run_scheme, uncompensated_scheme
from zencosim.manager.analysis.stable_step import largest_stable_step, scaled_scene
from zencosim.manager.scene.load import load_scene, scene_path

EXAMPLE_SCENES = ("two_mass_damped_fmu", "two_mass_damped_fmu3", "two_mass_damped_fmu_me", "two_mass_damped_python")
PYTHON_SCENE = str(resources.files("zencosim.examples").joinpath("scenes", "two_mass_damped_python.toml"))
RHO_TOLERANCE = 1e-8
STEP_TOLERANCE = 1e-3


def _steps(T: float, ratio: int = 1) -> list[str]:
    """Macro-step ``T`` with every micro-step equal to it (paper 000 §5.1), S2 at ``ratio`` times it."""
    return [f"manager.macro_step={T}", f"subsystems.S1.micro_step={T}", f"subsystems.S2.micro_step={T}",
            f"subsystems.S2.comm_ratio={ratio}"]


def _example(examples, name: str, overrides: list[str]):
    """The example scene and its built-in counterpart (the Model Exchange example integrates with rk4)."""
    built_in = overrides + (["subsystems.S1.integrator=rk4", "subsystems.S2.integrator=rk4"]
                            if name.endswith("_me") else [])
    return load_scene(str(examples / f"{name}.toml"), overrides), load_scene("two_mass_damped", built_in)


@pytest.mark.parametrize("T", [0.0005, 0.001, 0.0025, 0.004])
@pytest.mark.parametrize("name", EXAMPLE_SCENES)
def test_identified_examples_have_the_built_in_spectral_radius(examples, name, T):
    scene, built_in = _example(examples, name, _steps(T))
    identified = uncompensated_scheme(scene)
    exact = uncompensated_scheme(built_in)
    assert identified.spectral_radius == pytest.approx(exact.spectral_radius, abs=RHO_TOLERANCE)
    assert identified.stable == exact.stable  # 2.5 and 4 ms are unstable (paper 000 §5.2.3), 0.5 and 1 ms stable
    assert [(i.subsystem, i.order, i.exact) for i in identified.identifications] == [("S1", 2, True), ("S2", 2, True)]
    assert all(i.fit_residual < 1e-9 for i in identified.identifications)


@pytest.mark.parametrize("name", EXAMPLE_SCENES)
def test_identified_examples_have_the_built_in_largest_stable_step(examples, name):
    scene, built_in = _example(examples, name, _steps(0.001))
    identified, exact = largest_stable_step(scene), largest_stable_step(built_in)
    assert identified.largest_stable == pytest.approx(exact.largest_stable, rel=STEP_TOLERANCE)
    assert exact.largest_stable < exact.smallest_unstable <= exact.largest_stable * (1 + STEP_TOLERANCE)
    assert identified.unanalysable == 0
    # the boundary it brackets is the verdict's: stable at the lower end, unstable at the upper
    ends = [identified.largest_stable, identified.smallest_unstable]
    assert [uncompensated_scheme(scaled_scene(scene, round(t * 1e9))).stable for t in ends] == [True, False]


@pytest.mark.slow
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(m1=st.floats(0.5, 5.0), m2=st.floats(0.5, 5.0), k1=st.floats(1.0, 2000.0), k2=st.floats(1.0, 2000.0),
       c1=st.floats(0.01, 1.0), c2=st.floats(0.01, 1.0), kc=st.floats(1.0, 500.0), cc=st.floats(0.01, 1.0),
       T_us=st.integers(200, 5000), order=st.integers(0, 2), scheme=st.sampled_from(["jacobi", "gauss-seidel"]),
       ratio=st.integers(1, 2))
def test_generated_linear_python_models_have_the_built_in_analysis(m1, m2, k1, k2, c1, c2, kc, cc, T_us, order,
                                                                    scheme, ratio):
    """A random two-mass system, single- or multi-rate, Jacobi or Gauss–Seidel, extrapolation 0–2: as the user's
    Python model (``zencosim.examples.oscillator``) and as built-in ``masses`` subsystems."""
    common = _steps(T_us * 1e-6, ratio) + [f"manager.extrapolation={order}", f"manager.scheme={scheme}",
                                           f"manager.duration={T_us * ratio * 1e-3}"]  # 1000 periods: whole
    python = load_scene(PYTHON_SCENE, common + [
        f"subsystems.S1.start.m={m1}", f"subsystems.S1.start.k={k1}", f"subsystems.S1.start.c={c1}",
        f"subsystems.S1.start.kc={kc}", f"subsystems.S1.start.cc={cc}",
        f"subsystems.S2.start.m={m2}", f"subsystems.S2.start.k={k2}", f"subsystems.S2.start.c={c2}"])
    built_in = load_scene("two_mass_damped", common + [
        f"subsystems.S1.bodies.m1.mass={m1}", f"subsystems.S1.effects.k1.stiffness={k1}",
        f"subsystems.S1.effects.c1.damping={c1}", f"couplings.c.effects.kc.stiffness={kc}",
        f"couplings.c.effects.cc.damping={cc}",
        f"subsystems.S2.bodies.m2.mass={m2}", f"subsystems.S2.effects.k2.stiffness={k2}",
        f"subsystems.S2.effects.c2.damping={c2}"])
    identified, exact = uncompensated_scheme(python), uncompensated_scheme(built_in)
    assert identified.spectral_radius == pytest.approx(exact.spectral_radius,
                                                       abs=RHO_TOLERANCE * max(1.0, exact.spectral_radius))
    assert largest_stable_step(python).largest_stable == pytest.approx(largest_stable_step(built_in).largest_stable,
                                                                      rel=STEP_TOLERANCE)


def _two_mass_damped_with_s2(tmp_path, model: str, extra: str = "") -> str:
    """two_mass_damped with S2 a Python model whose point ``m2`` is the motion side; the scene file's path."""
    head, tail = scene_path("two_mass_damped").read_text().split("[subsystems.S2]")
    path = tmp_path / "scene.toml"
    path.write_text(f'{head}[subsystems.S2]\nmodel = "tests.manager.identified_models:{model}"\nmicro_step = 0.001\n'
                    f'{extra}points.m2 = {{ force_input = "f_in", position = "x", velocity = "v" }}\n\n'
                    + tail[tail.index("[couplings.c]"):])
    return str(path)


def test_a_pendulum_is_linearised_about_its_rest_and_predicts_small_motions(tmp_path):
    """The local linearisation of a nonlinear Python model: its ρ is that of its analytic linearisation (the
    built-in two_mass_damped, to the central differences' δ² ~ 1e-8), and the energy growth ``2 ln ρ / T`` it
    predicts is what a run at small amplitude (bob swinging ~1e-5 rad) measures, to 2 % (the slope of the energy
    envelope over the run's second half, docs/numerics.md, where the slower mode's decay has not quite gone); a run
    at large amplitude (~0.5 rad, the spring 1000 N/m of the linearisation softened by sin θ) does not."""
    # the pendulum's linearisation is S2's mass on a spring m g / L = 1000 N/m; 4 ms: unstable, ρ = 1.000356
    path = _two_mass_damped_with_s2(tmp_path, "Pendulum", 'start = { m = 1.0, L = 0.00981, g = 9.81, c = 0.1 }\n'
                                                          'energy = "E"\n')
    small_motion = _steps(0.004) + ["manager.duration=40", "subsystems.S1.bodies.m1.v0=0.001"]
    scheme = uncompensated_scheme(load_scene(path, small_motion))
    (pendulum,) = scheme.identifications
    assert (pendulum.subsystem, pendulum.exact, pendulum.order) == ("S2", False, 2)
    linearisation = uncompensated_scheme(load_scene("two_mass_damped", _steps(0.004)))
    assert scheme.spectral_radius == pytest.approx(linearisation.spectral_radius, abs=1e-8)
    assert run_scheme(load_scene(path, small_motion)) is None  # a local verdict is not the run's: it measures
    small = zencosim.run(load_scene(path, small_motion), "inproc").summary
    assert small["energy"]["growth_rate_per_s"] == pytest.approx(scheme.growth_rate, rel=0.02)
    large = zencosim.run(load_scene(path, [*small_motion, "subsystems.S1.bodies.m1.v0=0.5"]), "inproc").summary
    assert abs(large["energy"]["growth_rate_per_s"] - scheme.growth_rate) > 0.5 * scheme.growth_rate


def test_analyze_reports_identified_subsystems_in_its_json(examples, tmp_path, capsys):
    out = tmp_path / "a.json"
    overrides = [a for o in _steps(0.004) for a in ("--set", o)]
    assert main(["analyze", str(examples / "two_mass_damped_fmu.toml"), "--json", str(out), *overrides]) == 0
    stdout = capsys.readouterr().out
    report = json.loads(out.read_text())
    built_in = load_scene("two_mass_damped", _steps(0.004))
    exact = uncompensated_scheme(built_in)
    assert report["spectral_radius"]["uncompensated"] == pytest.approx(exact.spectral_radius, abs=RHO_TOLERANCE)
    assert report["stable"] == {"uncompensated": False, "compensated": None}
    assert report["growth_rate_per_s"]["uncompensated"] == pytest.approx(exact.growth_rate, rel=1e-4)
    assert {name: (entry["order"], entry["linearisation"]) for name, entry in report["identification"].items()} == {
        "S1": (2, "exact"), "S2": (2, "exact")}
    # unstable at 4 ms: the bracket is found by halving, then bisected
    assert report["largest_stable_step"]["largest_stable"] == pytest.approx(
        largest_stable_step(built_in).largest_stable, rel=STEP_TOLERANCE)
    assert len(report["poles"]["cosim_discrete"]) == 5  # four primary poles and the hold's real one
    for text in ("UNSTABLE", "compensator: built-in models only", "largest stable macro-step"):
        assert text in stdout


def test_a_subsystem_that_cannot_be_identified_is_refused_in_one_line(tmp_path, capsys):
    assert main(["analyze", _two_mass_damped_with_s2(tmp_path, "Overflowing")]) == 2
    err = capsys.readouterr().err
    assert "subsystem S2 cannot be identified: its responses to the probes are not finite" in err
    assert "Traceback" not in err


def test_a_run_of_fmus_takes_the_identified_verdict(examples):
    """The run summary's verdict on an FMU scene is the exact discrete one of its identification (as for a built-in
    linear scene, docs/numerics.md): unstable at 4 ms, where the energy of a 2 s run barely moves."""
    scene = load_scene(str(examples / "two_mass_damped_fmu.toml"), _steps(0.004) + ["manager.duration=2.0"])
    summary = zencosim.run(scene, "inproc").summary
    assert summary["stable_from"] == "exact discrete spectral radius" and summary["stable"] is False
    exact = uncompensated_scheme(load_scene("two_mass_damped", _steps(0.004)))
    assert summary["discrete"]["spectral_radius"] == pytest.approx(exact.spectral_radius, abs=RHO_TOLERANCE)


ONE_WAY = """name = "one_way"
description = "one oscillator drives another through a signal: no loop"
[manager]
duration = 1.0
macro_step = 0.001
[outputs]
reference = "none"
[subsystems.A]
model = "zencosim.examples.oscillator:Oscillator"
micro_step = 0.001
start = { k = 10.0, v0 = 1.0 }
outputs = ["x"]
[subsystems.B]
model = "zencosim.examples.oscillator:Oscillator"
micro_step = 0.001
start = { k = 100.0 }
outputs = ["x"]
[couplings.drive]
type = "signal"
output = "A.x"
input = "B.x_in"
"""


def test_a_source_and_a_sink_have_no_state_in_the_scheme(tmp_path):
    """Without a loop the scheme has nothing to destabilise (ρ = 0); the run's verdict is then measured, as a
    subsystem's own modes are outside ``Ψ``."""
    (tmp_path / "one_way.toml").write_text(ONE_WAY)
    scene = load_scene(str(tmp_path / "one_way.toml"))
    scheme = uncompensated_scheme(scene)
    assert [(i.subsystem, i.role, i.order, i.probes) for i in scheme.identifications] == [
        ("A", "source", 0, 0), ("B", "sink", 0, 0)]
    assert scheme.spectral_radius == 0.0 and scheme.stable
    assert run_scheme(scene) is None
