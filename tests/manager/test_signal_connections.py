"""Signal connections (couplings type = "signal"): an output variable copied into an input variable at every
communication point, with SSP's linear transformation, checked against FMPy running the same FMUs; refusals that
name both ends."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import zencosim

fmpy = pytest.importorskip("fmpy")

SOURCE = {"m": 1.0, "k": 10.0, "c": 0.2, "kc": 5.0, "cc": 0.5, "x0": 0.3}  # x_in = v_in = 0: fc = 5 x + 0.5 v
TARGET = {"m": 2.0, "k": 40.0, "c": 0.1}
FACTOR, OFFSET = -2.5, 0.75
STEP, DURATION = 0.01, 2.0


def scene(directory: Path, output: str = "S1.fc", input: str = "S2.f_in", extra: str = "") -> Path:
    path = directory / "signal.toml"
    path.write_text(f"""
name = "signal"
[manager]
duration = {DURATION}
macro_step = {STEP}
extrapolation = 0
[outputs]
reference = "none"
[subsystems.S1]
model = "fmu"
fmu = "oscillator_fmi2.fmu"
micro_step = {STEP}
start = {{ {", ".join(f"{k} = {v}" for k, v in SOURCE.items())} }}
outputs = ["x", "v"]
[subsystems.S2]
model = "fmu"
fmu = "oscillator_fmi2.fmu"
micro_step = {STEP}
start = {{ {", ".join(f"{k} = {v}" for k, v in TARGET.items())} }}
outputs = "all"
[couplings.u]
type = "signal"
output = "{output}"
input = "{input}"
factor = {FACTOR}
offset = {OFFSET}
{extra}
""")
    return path


def test_the_input_receives_the_transformed_output_as_fmpy_running_the_same_fmus_gives(examples):
    result = zencosim.run(zencosim.load_scene(str(scene(examples))))
    fmu = str(examples / "oscillator_fmi2.fmu")
    source = fmpy.simulate_fmu(fmu, start_values=SOURCE, stop_time=DURATION, output_interval=STEP, output=["fc"])
    # ZOH over a macro-step, as FMPy applies an input at the start of each step: the samples are the input table
    table = np.array(list(zip(source["time"], FACTOR * source["fc"] + OFFSET)),
                     dtype=[("time", float), ("f_in", float)])
    target = fmpy.simulate_fmu(fmu, start_values=TARGET, stop_time=DURATION, output_interval=STEP, input=table,
                               output=["x", "v"])
    # the signal as exchanged (and recorded) is what the input received; FMPy passes each doStep
    # (n + 1) h - n h, which can differ from h in the last bit, so the two agree to round-off, not to the bit
    tolerance = 1e-12 * np.abs(table["f_in"]).max()
    np.testing.assert_allclose(result.signal("u").values, table["f_in"], rtol=0, atol=tolerance)
    for name in ("x", "v"):
        reference = target[name]
        assert np.abs(result.signal(f"S2.{name}").values - reference).max() <= 1e-12 * np.abs(reference).max()
    assert np.ptp(result.signal("S2.x").values) > 0.01  # the input moved the target


@pytest.mark.multiprocess
def test_a_signal_connection_gives_one_digest_on_both_buses(examples):
    path = str(scene(examples))
    assert zencosim.run(path).digest == zencosim.run(path, bus="zenoh").digest


@pytest.mark.parametrize("output, input, key, reason", [
    ("S1.x", "S2.f_in", "couplings.u",
     "S1.x [m] feeds S2.f_in [N]: not the same quantity"),
    ("S1.x_in", "S2.f_in", "couplings.u.output", "S1: x_in is input; expected an output"),
    ("S1.fc", "S2.nothing", "couplings.u.input",
     "S2: the FMI 2.0 Co-Simulation has no variable 'nothing' of type Real, Integer or Boolean"),
    ("S3.fc", "S2.f_in", "couplings.u.output", "unknown subsystem 'S3'; expected one of S1, S2"),
])
def test_a_bad_signal_connection_names_its_ends(examples, output, input, key, reason):
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(scene(examples, output, input)))
    assert (key, reason) in [(p.key, p.reason) for p in caught.value.problems]


def test_a_builtin_model_has_no_variables_to_connect(tmp_path):
    text = (Path(zencosim.load_scene("two_mass_damped").path).read_text()
            + '\n[couplings.s]\ntype = "signal"\noutput = "S1.x1"\ninput = "S2.f"\n')
    (tmp_path / "scene.toml").write_text(text)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(tmp_path / "scene.toml"))
    assert ("couplings.s.output", "model masses of S1 has no variables by name: a signal connection joins variables "
            "of FMUs and Python models") in [(p.key, p.reason) for p in caught.value.problems]


def test_a_recorded_signal_connection_verifies_and_exports_the_signal(examples):
    # S1 has no inputs at all: its commands carry no coefficients
    path = scene(examples)
    recording = examples / "signal.mcap"  # beside the FMUs: the recorded scene names them relative to itself
    result = zencosim.run(zencosim.load_scene(str(path)), record=recording)
    run = subprocess.run([sys.executable, "-m", "zencosim", "replay", str(recording), "--verify"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "verify passed" in run.stdout, run.stdout + run.stderr
    loaded = zencosim.load_recording(recording)
    np.testing.assert_array_equal(loaded.signal("u").values, result.signal("u").values)


def test_a_connection_extrapolates_with_its_own_order(examples):
    # the subsystems hold their inputs (manager.extrapolation = 0); the connection asks for FOH, which the target
    # (two doSteps per macro-step) sees at the start of each half step: FMPy given those values as its input
    path = scene(examples, extra="extrapolation = 1")
    half = STEP / 2
    scene_ = zencosim.load_scene(str(path), {"subsystems.S2.micro_step": half})
    result = zencosim.run(scene_)
    assert scene_.couplings["u"].settings.extrapolation == 1
    fmu = str(examples / "oscillator_fmi2.fmu")
    source = fmpy.simulate_fmu(fmu, start_values=SOURCE, stop_time=DURATION, output_interval=STEP, output=["fc"])
    u = FACTOR * source["fc"] + OFFSET
    slope = np.concatenate(([0.0], np.diff(u))) / STEP  # FOH through the last two samples (one at the start)
    times = np.repeat(source["time"], 2) + np.tile([0.0, half], len(u))
    values = np.repeat(u, 2) + np.tile([0.0, half], len(u)) * np.repeat(slope, 2)
    table = np.array(list(zip(times, values)), dtype=[("time", float), ("f_in", float)])
    target = fmpy.simulate_fmu(fmu, start_values=TARGET, stop_time=DURATION, output_interval=half, input=table,
                               output=["x"])
    reference = target["x"][::2]
    assert np.abs(result.signal("S2.x").values - reference).max() <= 1e-12 * np.abs(reference).max()
    held = zencosim.run(zencosim.load_scene(str(scene(examples)), {"subsystems.S2.micro_step": half}))
    assert np.abs(held.signal("S2.x").values - reference).max() > 1e-6  # the order matters here


class Gain:
    """y = gain × u at the same instant (direct feedthrough); one state that does nothing."""

    inputs = {"u": "N"}
    outputs = {"y": "N"}
    feedthrough = {"y": ("u",)}
    parameters = {"gain": 0.5}

    def __init__(self, gain: float) -> None:
        self.gain = gain

    def initial_state(self):
        return np.zeros(1)

    def derivative(self, t, z, u):
        return np.zeros(1)

    def outputs_at(self, t, z, u):
        return np.array([self.gain * u[0]])


def test_a_loop_of_feedthrough_outputs_through_signal_connections_is_refused_naming_it(tmp_path):
    path = tmp_path / "loop.toml"
    model = f"{__name__}:Gain"
    path.write_text(f"""name = "loop"
[manager]
duration = 0.01
macro_step = 0.001
[outputs]
reference = "none"
[subsystems.A]
model = "{model}"
micro_step = 0.001
[subsystems.B]
model = "{model}"
micro_step = 0.001
[couplings.ab]
type = "signal"
output = "A.y"
input = "B.u"
[couplings.ba]
type = "signal"
output = "B.y"
input = "A.u"
""")
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.run(zencosim.load_scene(str(path)))
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        ("couplings", "outputs with direct feedthrough form an algebraic loop: A.ab <- B.ba <- A.ab; an explicit "
                      "scheme cannot initialise them")]


def test_check_lists_the_signal_connections(examples):
    run = subprocess.run([sys.executable, "-m", "zencosim", "check", str(scene(examples, extra="extrapolation = 1"))],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "200"})
    assert run.returncode == 0, run.stderr
    assert f"signal connections: u (S1.fc -> S2.f_in, × {FACTOR:g} + {OFFSET:g}, order 1)" in run.stdout
