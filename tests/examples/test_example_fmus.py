"""The example oscillator FMUs: built from their C sources with gcc, loaded and run through fmpy."""
from __future__ import annotations

import ctypes
import re
import shutil
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # raised for a status worse than warning
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Slave

from zencosim.examples.fmus import build
from zencosim.examples.fmus.build import build_fmu

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="building the example FMUs needs gcc")

OUTPUTS = ("x", "v", "a", "fc", "inverse_mass", "E")
INPUTS = ("x_in", "v_in", "f_in")
COUPLED = {"m": 2.0, "k": 3.0, "c": 0.5, "kc": 7.0, "cc": 0.3, "x0": 0.4, "v0": -1.2}


@dataclass(frozen=True)
class Built:
    """An FMU built for the session: its file, its model description and where it was extracted."""

    path: Path
    md: object
    unzipdir: str


def _build(tmp_path_factory, name: str, **options) -> Built:
    folder = tmp_path_factory.mktemp(name)
    path = build_fmu(folder / f"{name}.fmu", **options)
    md = fmpy.read_model_description(path, validate_model_structure=True)  # schema and ModelStructure checks
    return Built(path, md, str(fmpy.extract(path, folder / "unzipped")))


@pytest.fixture(scope="session")
def fmu2(tmp_path_factory) -> Built:
    return _build(tmp_path_factory, "fmu2", fmi_version=2, interfaces=("cs", "me"))


@pytest.fixture(scope="session")
def fmu2_me(tmp_path_factory) -> Built:
    return _build(tmp_path_factory, "fmu2_me", fmi_version=2, interfaces=("me",))


@pytest.fixture(scope="session")
def fmu2_stateless(tmp_path_factory) -> Built:
    return _build(tmp_path_factory, "fmu2_stateless", fmi_version=2, can_get_and_set_state=False)


@pytest.fixture(scope="session")
def fmu3(tmp_path_factory) -> Built:
    return _build(tmp_path_factory, "fmu3", fmi_version=3)


@pytest.fixture(params=["fmu2", "fmu3"])
def cs_fmu(request) -> Built:
    """Each Co-Simulation FMU in turn: FMI 2.0 and FMI 3.0."""
    return request.getfixturevalue(request.param)


class Oscillator:
    """A Co-Simulation instance of an example FMU (FMI 2.0 or 3.0), its variables by name.

    ``parameters`` are set before initialization mode is entered; the instance is in step mode after.
    """

    def __init__(self, fmu: Built, **parameters: float):
        md = fmu.md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmi3 = md.fmiVersion.startswith("3")
        slave = FMU3Slave if self.fmi3 else FMU2Slave
        self.fmu = slave(guid=md.guid, unzipDirectory=fmu.unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                         instanceName="oscillator")
        self.fmu.instantiate()
        if not self.fmi3:
            self.fmu.setupExperiment(startTime=0.0)
        self.set(**parameters)
        if self.fmi3:
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set(self, **values: float) -> None:
        names = list(values)
        setter = self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal
        setter([self.vr[n] for n in names], [float(values[n]) for n in names])

    def get(self, *names: str) -> list[float]:
        getter = self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal
        return getter([self.vr[n] for n in names])

    def outputs(self) -> dict[str, float]:
        return dict(zip(OUTPUTS, self.get(*OUTPUTS)))

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)

    def close(self) -> None:
        self.fmu.freeInstance()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def formulas(p: dict[str, float], x: float, v: float, x_in: float, v_in: float, f_in: float) -> dict[str, float]:
    """The model's outputs written out in Python (the operations in the order the C code does them)."""
    m, k, c, kc, cc = (p[n] for n in ("m", "k", "c", "kc", "cc"))
    fc = kc * (x - x_in) + cc * (v - v_in)  # on the terminal: the mass feels -fc
    return {"x": x, "v": v, "a": (-k * x - c * v - fc + f_in) / m, "fc": fc, "inverse_mass": 1 / m,
            "E": 0.5 * m * v * v + 0.5 * k * x * x + 0.5 * kc * (x - x_in) * (x - x_in)}


def inputs_at(i: int) -> dict[str, float]:
    """A deterministic, nonzero input sequence."""
    return {"x_in": 0.1 * np.sin(0.01 * i), "v_in": 0.001 * np.cos(0.01 * i), "f_in": 0.5 + 0.2 * np.sin(0.03 * i)}


def run(osc: Oscillator, start: int, steps: int, h: float) -> np.ndarray:
    """Steps from t = start*h with the input sequence; the outputs after each step, one row per step."""
    rows = []
    for i in range(start, start + steps):
        osc.set(**inputs_at(i))
        osc.step(i * h, h)
        rows.append(osc.get("time", *OUTPUTS))
    return np.array(rows)


# ---- the binaries and model descriptions ----

@pytest.mark.parametrize("version", [2, 3])
def test_every_function_of_the_fmi_c_api_is_exported(version, request):
    fmu = request.getfixturevalue(f"fmu{version}")
    header = (build.fmi_headers() / f"fmi{version}Functions.h").read_text()
    names = re.findall(rf"FMI{version}_Export\s+fmi{version}\w+TYPE\s+(fmi{version}\w+);", header)
    assert len(names) > 40
    library = ctypes.CDLL(str(Path(fmu.unzipdir, "binaries", build.PLATFORM[version],
                                   build.MODEL_IDENTIFIER[version] + ".so")))
    assert [n for n in names if not hasattr(library, n)] == []


def test_the_model_descriptions_offer_the_interfaces_asked_for(fmu2, fmu2_me, fmu3):
    assert (fmu2.md.coSimulation.modelIdentifier, fmu2.md.modelExchange.modelIdentifier) == ("zencosim_oscillator",) * 2
    assert fmu2_me.md.coSimulation is None and fmu2_me.md.modelExchange is not None
    assert fmu3.md.modelExchange is None and fmu3.md.coSimulation.modelIdentifier == "zencosim_oscillator3"
    for fmu in (fmu2, fmu3):
        assert fmu.md.modelName == "zencosim oscillator"
        assert fmu.md.coSimulation.canHandleVariableCommunicationStepSize
        assert fmu.md.coSimulation.canGetAndSetFMUstate and fmu.md.coSimulation.canSerializeFMUstate
        assert [(d.variable.derivative.name, d.variable.name) for d in fmu.md.derivatives] == [("x", "v"), ("v", "a")]
    assert fmu2.md.numberOfEventIndicators == 0
    assert (fmu2.md.guid, fmu3.md.guid) == ("{zencosim-oscillator-fmi2-2}", "{zencosim-oscillator-fmi3-2}")
    with pytest.raises(ValueError, match="interfaces"):
        build_fmu(Path("unused.fmu"), fmi_version=3, interfaces=("cs", "me"))


def test_parameters_and_inputs_have_the_declared_start_values(fmu2, fmu3):
    starts = {"m": 1.0, "k": 0.0, "c": 0.0, "kc": 0.0, "cc": 0.0, "x0": 0.0, "v0": 0.0, "fail_at": 1e300,
              "x_in": 0.0, "v_in": 0.0, "f_in": 0.0}
    for fmu in (fmu2, fmu3):
        declared = {v.name: float(v.start) for v in fmu.md.modelVariables if v.start is not None}
        assert declared == starts
        assert {v.name: (v.causality, v.variability) for v in fmu.md.modelVariables if v.name in starts} == {
            n: ("input", "continuous") if n in INPUTS else ("parameter", "fixed") for n in starts}
        with Oscillator(fmu) as osc:
            assert dict(zip(starts, osc.get(*starts))) == starts


# SI base-unit exponents of each variable, written out here independently of build.py's unit table
DIMENSIONS = {
    "time": {"s": 1}, "m": {"kg": 1}, "k": {"kg": 1, "s": -2}, "c": {"kg": 1, "s": -1}, "kc": {"kg": 1, "s": -2},
    "cc": {"kg": 1, "s": -1}, "x0": {"m": 1}, "v0": {"m": 1, "s": -1}, "fail_at": {"s": 1}, "x_in": {"m": 1},
    "v_in": {"m": 1, "s": -1}, "f_in": {"kg": 1, "m": 1, "s": -2}, "x": {"m": 1}, "v": {"m": 1, "s": -1},
    "a": {"m": 1, "s": -2}, "fc": {"kg": 1, "m": 1, "s": -2}, "inverse_mass": {"kg": -1},
    "E": {"kg": 1, "m": 2, "s": -2},
}


@pytest.mark.parametrize("version", [2, 3])
def test_every_variable_has_a_unit_that_resolves_to_si_base_units(version, request):
    md = request.getfixturevalue(f"fmu{version}").md
    units = {u.name: u.baseUnit for u in md.unitDefinitions}
    assert {v.name for v in md.modelVariables} == set(DIMENSIONS)
    for v in md.modelVariables:
        assert v.type == ("Real" if version == 2 else "Float64")
        base = units[v.unit]
        exponents = {e: getattr(base, e) for e in ("kg", "m", "s", "A", "K", "mol", "cd", "rad") if getattr(base, e)}
        assert (v.name, exponents, base.factor, base.offset) == (v.name, DIMENSIONS[v.name], 1.0, 0.0)


@pytest.mark.parametrize("version", [2, 3])
def test_the_declared_input_dependencies_are_the_inputs_each_output_responds_to(version, request):
    """Direct feedthrough, as declared in ModelStructure/Outputs, against what the outputs do."""
    fmu = request.getfixturevalue(f"fmu{version}")
    declared = {u.variable.name: {d.name for d in u.dependencies if d.causality == "input"} for u in fmu.md.outputs}
    assert declared == {"x": set(), "v": set(), "a": set(INPUTS), "fc": {"x_in", "v_in"}, "inverse_mass": set(),
                        "E": {"x_in"}}
    with Oscillator(fmu, **COUPLED) as osc:
        osc.set(x_in=0.1, v_in=0.2, f_in=0.3)
        before = osc.outputs()
        responds = {name: set() for name in OUTPUTS}
        for i in INPUTS:
            osc.set(**{i: 1.7})
            for name, value in osc.outputs().items():
                if value != before[name]:
                    responds[name].add(i)
            osc.set(x_in=0.1, v_in=0.2, f_in=0.3)
    assert responds == declared


# ---- Co-Simulation ----

def test_a_free_oscillation_is_the_symplectic_euler_recurrence(fmu2):
    m, k, c, h, n = 1.0, 10.0, 0.1, 1e-3, 2000
    x, v = np.empty(n + 1), np.empty(n + 1)
    x[0], v[0] = 0.0, 1.0
    for i in range(n):
        a = (-k * x[i] - c * v[i]) / m
        v[i + 1] = v[i] + h * a
        x[i + 1] = x[i] + h * v[i + 1]
    with Oscillator(fmu2, m=m, k=k, c=c, x0=0.0, v0=1.0) as osc:
        states = [osc.get("x", "v")]
        for i in range(n):
            osc.step(i * h, h)
            states.append(osc.get("x", "v"))
        assert osc.get("time") == [pytest.approx(n * h, rel=1e-15)]
    states = np.array(states)
    # the same method in C and in numpy, but the C code adds -fc + f_in (both zero here) and may order the
    # operations differently: agreement to a few rounding errors, not necessarily to the bit
    for column, reference in ((states[:, 0], x), (states[:, 1], v)):
        np.testing.assert_allclose(column, reference, rtol=1e-12, atol=1e-12 * np.abs(reference).max())
    assert np.abs(x).max() > 0.25  # it did oscillate: amplitude about v0/sqrt(k/m)


def test_fmi3_gives_the_fmi2_trajectory_bit_for_bit(fmu2, fmu3):
    free = {"m": 1.0, "k": 10.0, "c": 0.1, "v0": 1.0}
    for parameters, inputs in ((free, False), (COUPLED, True)):
        runs = []
        for fmu in (fmu2, fmu3):
            with Oscillator(fmu, **parameters) as osc:
                rows = []
                for i in range(2000):
                    if inputs:
                        osc.set(**inputs_at(i))
                    osc.step(i * 1e-3, 1e-3)
                    rows.append(osc.get("time", *OUTPUTS))
                runs.append(np.array(rows))
        assert np.array_equal(runs[0], runs[1])  # the same C arithmetic in both sources


def test_outputs_match_their_formulas_and_a_step_is_kick_then_drift(cs_fmu):
    h = 0.01
    with Oscillator(cs_fmu, **COUPLED) as osc:
        assert osc.get("x", "v") == [COUPLED["x0"], COUPLED["v0"]]
        for i in range(30):
            inputs = inputs_at(100 * i)
            osc.set(**inputs)
            out = osc.outputs()
            expected = formulas(COUPLED, out["x"], out["v"], **inputs)
            # the same operations as the C code, in IEEE double arithmetic: a small tolerance only in
            # case a compiler reorders; any wrong term would be off by far more
            assert out == pytest.approx(expected, rel=1e-14, abs=1e-15)
            osc.step(i * h, h)
            x, v = osc.get("x", "v")
            assert v == out["v"] + h * out["a"]  # kick with the acceleration at the start of the step
            assert x == out["x"] + h * v  # then drift with the new velocity
        assert out["fc"] != 0.0 and out["E"] > 0.0 and out["inverse_mass"] == 0.5


def test_x0_and_v0_give_the_start_whether_set_before_or_in_initialization_mode(cs_fmu):
    with Oscillator(cs_fmu, x0=0.3, v0=-0.2) as osc:
        assert osc.get("x", "v") == [0.3, -0.2]
    with Oscillator(cs_fmu) as osc:
        assert osc.get("x", "v") == [0.0, 0.0]
    md = cs_fmu.md
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = (FMU3Slave if md.fmiVersion.startswith("3") else FMU2Slave)(
        guid=md.guid, unzipDirectory=cs_fmu.unzipdir, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    try:
        if isinstance(slave, FMU3Slave):
            slave.enterInitializationMode(startTime=0.0)
            slave.setFloat64([vr["x0"], vr["v0"]], [0.7, 0.9])
            slave.exitInitializationMode()
            assert slave.getFloat64([vr["x"], vr["v"]]) == [0.7, 0.9]
            with pytest.raises(FMICallException):  # a fixed parameter, after initialization
                slave.setFloat64([vr["k"]], [1.0])
        else:
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.setReal([vr["x0"], vr["v0"]], [0.7, 0.9])
            slave.exitInitializationMode()
            assert slave.getReal([vr["x"], vr["v"]]) == [0.7, 0.9]
            with pytest.raises(FMICallException):
                slave.setReal([vr["k"]], [1.0])
    finally:
        slave.freeInstance()


def test_a_step_at_or_after_fail_at_fails_and_leaves_the_state_alone(cs_fmu, capsys):
    h = 0.25  # steps that end exactly on fail_at: binary fractions
    function = "fmi3DoStep" if cs_fmu.md.fmiVersion.startswith("3") else "fmi2DoStep"
    with Oscillator(cs_fmu, k=1.0, v0=1.0, fail_at=1.0) as osc:
        for i in range(4):
            osc.step(i * h, h)  # the last starts at 0.75 < fail_at
        before = osc.get("time", "x", "v")
        with pytest.raises(FMICallException) as failure:
            osc.step(4 * h, h)
        assert (failure.value.function, failure.value.status) == (function, 3)  # fmi2Error / fmi3Error
        with pytest.raises(FMICallException):
            osc.step(5 * h, h)
        assert osc.get("time", "x", "v") == before
    assert "at or after fail_at" in capsys.readouterr().out  # fmpy's default logger prints the FMU's message


# ---- FMU state ----

def test_get_and_set_fmu_state_roll_back_exactly(cs_fmu):
    h = 1e-3
    with Oscillator(cs_fmu, **COUPLED) as osc:
        run(osc, 0, 100, h)
        state = osc.fmu.getFMUState()  # fmpy's FMU2Slave has the FMI 3.0 names as aliases of getFMUstate, …
        first = run(osc, 100, 50, h)
        osc.fmu.setFMUState(state)
        assert osc.get("time") == [100 * h]
        again = run(osc, 100, 50, h)
        osc.fmu.freeFMUState(state)
    assert np.array_equal(first, again)


def test_a_serialized_state_is_time_x_v_and_restores_in_another_instance(cs_fmu):
    h = 1e-3
    with Oscillator(cs_fmu, **COUPLED) as osc, Oscillator(cs_fmu, **COUPLED) as other:
        run(osc, 0, 100, h)
        state = osc.fmu.getFMUState()
        serialized = osc.fmu.serializeFMUState(state)
        assert serialized == struct.pack("=3d", *osc.get("time", "x", "v"))  # 24 bytes
        restored = other.fmu.deserializeFMUState(serialized)
        other.fmu.setFMUState(restored)
        assert np.array_equal(run(osc, 100, 50, h), run(other, 100, 50, h))
        osc.fmu.freeFMUState(state)
        other.fmu.freeFMUState(restored)


def test_a_variant_without_state_declares_it_and_refuses(fmu2_stateless):
    cs = fmu2_stateless.md.coSimulation
    assert (cs.canGetAndSetFMUstate, cs.canSerializeFMUstate) == (False, False)
    with Oscillator(fmu2_stateless) as osc:
        with pytest.raises(FMICallException) as failure:
            osc.fmu.getFMUstate()
        assert failure.value.function == "fmi2GetFMUstate"


# ---- Model Exchange ----

def test_model_exchange_derivatives_are_v_and_a(fmu2):
    md = fmu2.md
    vr = {v.name: v.valueReference for v in md.modelVariables}
    model = FMU2Model(guid=md.guid, unzipDirectory=fmu2.unzipdir, modelIdentifier=md.modelExchange.modelIdentifier)
    model.instantiate()
    try:
        parameters = {**COUPLED, "fail_at": 2.0}
        model.setReal([vr[n] for n in parameters], list(parameters.values()))
        model.setupExperiment(startTime=0.0)
        model.enterInitializationMode()
        model.exitInitializationMode()
        assert model.newDiscreteStates()[0] is False  # no event iteration needed
        model.enterContinuousTimeMode()
        states, derivatives = (ctypes.c_double * 2)(), (ctypes.c_double * 2)()
        model.getContinuousStates(states, 2)
        assert list(states) == [COUPLED["x0"], COUPLED["v0"]]
        for t, x, v in ((0.5, 0.25, -0.75), (1.0, -1.5, 2.0), (1.5, 0.0, 0.0)):
            inputs = {"x_in": 0.3 * t, "v_in": -0.1, "f_in": 1.0 + t}
            model.setTime(t)
            model.setContinuousStates((ctypes.c_double * 2)(x, v), 2)
            model.setReal([vr[n] for n in inputs], list(inputs.values()))
            model.getDerivatives(derivatives, 2)
            expected = formulas(parameters, x, v, **inputs)
            assert list(derivatives) == [v, pytest.approx(expected["a"], rel=1e-14, abs=1e-15)]
            assert model.getReal([vr["x"], vr["v"], vr["a"]]) == [x, v, derivatives[1]]
        model.setTime(2.0)  # fail_at
        with pytest.raises(FMICallException) as failure:
            model.getDerivatives(derivatives, 2)
        assert (failure.value.function, failure.value.status) == ("fmi2GetDerivatives", 3)
    finally:
        model.freeInstance()


# ---- building ----

def test_a_compile_error_raises_runtime_error_with_gccs_message(tmp_path):
    broken = tmp_path / "broken.c"
    broken.write_text('#error "deliberately broken for the test"\n')
    with pytest.raises(RuntimeError, match="deliberately broken for the test") as failure:
        build._compile(broken, tmp_path / "broken.so", [])
    assert "broken.c" in str(failure.value)
    with pytest.raises(RuntimeError, match="No such file or directory"):
        build._compile(tmp_path / "missing.c", tmp_path / "missing.so", [])
