"""Integer and Boolean signal connections between FMUs exported by pythonfmu, against libcosim on the same FMUs:
the example oscillator's position drives a threshold FMU (Boolean and Integer outputs), whose outputs drive a gate
FMU (Boolean and Integer inputs, a Real output). Both tools exchange at the same instants with the inputs held over
a step; the gate's output, made of the discrete values, must agree sample for sample."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import zencosim
from zencosim.examples.write import write_examples

pytest.importorskip("pythonfmu")

STEP, DURATION = 0.01, 3.0
PLANT_START = {"m": 1.0, "k": 10.0, "x0": 1.0}  # x = cos(√10 t): it crosses the threshold both ways

SOURCES = {"zencosim_threshold": '''\
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Integer, Real


class Threshold(Fmi2Slave):
    """above = x > 0.5; count: the steps so far that ended above."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x, self.above, self.count = 0.0, False, 0
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Boolean("above", causality=Fmi2Causality.output))
        self.register_variable(Integer("count", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.above = self.x > 0.5
        self.count += int(self.above)
        return True
''', "zencosim_gate": '''\
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Integer, Real


class Gate(Fmi2Slave):
    """y = n while enabled, else -1."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.enable, self.n, self.y = False, 0, -1.0
        self.register_variable(Boolean("enable", causality=Fmi2Causality.input))
        self.register_variable(Integer("n", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.y = float(self.n) if self.enable else -1.0
        return True
'''}
CONNECTIONS = (("plant", "x", "threshold", "x"), ("threshold", "above", "gate", "enable"),
               ("threshold", "count", "gate", "n"))


@pytest.fixture(scope="module")
def system(tmp_path_factory) -> dict[str, Path]:
    from pythonfmu.builder import FmuBuilder
    directory = tmp_path_factory.mktemp("discrete")
    write_examples(directory / "examples")
    shutil.copy(directory / "examples" / "oscillator_fmi2.fmu", directory / "plant.fmu")
    names = {}
    for module, source in SOURCES.items():
        path = directory / "source" / f"{module}.py"
        path.parent.mkdir(exist_ok=True)
        path.write_text(source)
        names[module] = Path(FmuBuilder.build_FMU(path, dest=directory)).name
    fmus = {"plant": "plant.fmu", "threshold": names["zencosim_threshold"], "gate": names["zencosim_gate"]}
    start = {"plant": PLANT_START}
    scene = directory / "discrete.toml"
    scene.write_text(f"name = \"discrete\"\n[manager]\nduration = {DURATION}\nmacro_step = {STEP}\n"
                     "[outputs]\nreference = \"none\"\n"
                     + "".join(f"[subsystems.{name}]\nmodel = \"fmu\"\nfmu = \"{fmu}\"\nmicro_step = {STEP}\n"
                               + (f"start = {{ {', '.join(f'{k} = {v}' for k, v in start[name].items())} }}\n"
                                  if name in start else "")
                               + ("units = { x = \"m\" }\n" if name == "threshold" else "")
                               + ("outputs = [\"y\"]\n" if name == "gate" else "")
                               for name, fmu in fmus.items())
                     + "".join(f"[couplings.{source}_{output}]\ntype = \"signal\"\noutput = \"{source}.{output}\"\n"
                               f"input = \"{target}.{variable}\"\n"
                               for source, output, target, variable in CONNECTIONS))
    simulators = "".join(
        f'<Simulator name="{name}" source="{fmu}" stepSize="{STEP}"><InitialValues>'
        + "".join(f'<InitialValue variable="{k}"><Real value="{float(v)}"/></InitialValue>'
                  for k, v in start.get(name, {}).items())
        + "</InitialValues></Simulator>" for name, fmu in fmus.items())
    connections = "".join(f'<VariableConnection><Variable simulator="{s}" name="{o}"/>'
                          f'<Variable simulator="{t}" name="{i}"/></VariableConnection>' for s, o, t, i in CONNECTIONS)
    osp = directory / "OspSystemStructure.xml"
    osp.write_text('<?xml version="1.0" encoding="utf-8"?>\n<OspSystemStructure xmlns="http://opensimulationplatform'
                   f'.com/MSMI/OSPSystemStructure" version="0.1"><StartTime>0.0</StartTime><BaseStepSize>{STEP}'
                   f'</BaseStepSize><Algorithm>fixedStep</Algorithm><Simulators>{simulators}</Simulators>'
                   f'<Connections>{connections}</Connections></OspSystemStructure>')
    return {"scene": scene, "osp": osp}


def test_integer_and_boolean_connections_give_libcosims_answer(system):
    pytest.importorskip("libcosimpy")
    from tests.interop.libcosim_oracle import run_osp

    ours = zencosim.run(zencosim.load_scene(str(system["scene"])))
    theirs = run_osp(system["osp"], DURATION, [("gate", "y"), ("plant", "x")])
    # the discrete values travel as float64 and are converted at each FMU's boundary: y holds them exactly
    y = ours.signal("y").values
    np.testing.assert_array_equal(y, theirs[("gate", "y")])
    assert len(np.unique(y[y >= 0])) > 5 and (y == -1.0).any()  # counted, and gated off and on
    assert np.array_equal(ours.signal("threshold_above").values, ours.signal("threshold_above").values.round())
    x = theirs[("plant", "x")]  # the plant agrees to rounding (libcosim's doStep size: docs/interop.md)
    assert np.abs(ours.signal("plant_x").values - x).max() <= 1e-12 * np.abs(x).max()


def test_a_discrete_connection_is_held_over_a_step_and_cannot_be_extrapolated(system, tmp_path):
    text = system["scene"].read_text().replace('input = "gate.n"\n', 'input = "gate.n"\nextrapolation = 1\n')
    path = system["scene"].with_name("extrapolated.toml")
    path.write_text(text)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(path))
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        ("couplings.threshold_count.extrapolation", "an Integer is held over a step; expected 0")]


def test_a_boolean_into_a_real_is_refused_naming_both_types(system):
    text = system["scene"].read_text().replace('output = "threshold.above"', 'output = "plant.v"')
    path = system["scene"].with_name("mixed.toml")
    path.write_text(text)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(path))
    assert ("couplings.threshold_above", "plant.v (Real) feeds gate.enable (Boolean): expected one type") in \
        [(p.key, p.reason) for p in caught.value.problems]
