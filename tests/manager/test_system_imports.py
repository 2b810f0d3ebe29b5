"""Importing OSP system structures and SSP systems as scene documents (manager.scene.imports).

The two-mass oscillator of paper 000 as two instances of one FMU (only a modelDescription.xml: nothing
is run): the imported document equals the TOML scene written by hand; whatever cannot be mapped is a
SceneError naming the file and the element, never a traceback.
"""
from __future__ import annotations

import contextlib
import io
import shutil
import tomllib
import zipfile
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.interop.peer_pair import ecco_configuration
from zencosim.cli.main import main
from zencosim.manager.scene.imports import import_system
from zencosim.manager.scene.load import SceneError, load_scene, scene_from_text

SCENE = """
name = "two_mass_damped_fmu"
description = "DESCRIPTION"

[manager]
duration = 10.0
macro_step = 0.001

[outputs]
signals = ["COUPLING.x", "COUPLING.f"]
reference = "none"

[subsystems.S1]
model = "fmu"
fmu = "FMU"
micro_step = 0.001
start = { m = 1.0, k = 10.0, c = 0.1, kc = 100.0, cc = 0.1, v0 = 100.0 }
energy = "E"
points.p1 = { force = "fc", position_input = "x_in", velocity_input = "v_in" }

[subsystems.S2]
model = "fmu"
fmu = "FMU"
micro_step = 0.001
start = { m = 1.0, k = 1000.0, c = 0.1, v0 = -100.0 }
energy = "E"
points.p2 = { force_input = "f_in", position = "x", velocity = "v" }

[couplings.COUPLING]
type = "force_displacement"
force_side = "S1.p1"
motion_side = "S2.p2"
force = "COUPLING.f"
displacement = "COUPLING.x"
velocity = "COUPLING.v"
"""


def expected(description: str, coupling: str = "c1", fmu: str = "oscillator.fmu") -> dict:
    text = SCENE.replace("DESCRIPTION", description).replace("COUPLING", coupling).replace("FMU", fmu)
    return tomllib.loads(text)


# An FMU of the oscillator: one mass with spring and damper to the ground, a coupling element (kc, cc) to a
# received motion (force side) and an applied force (motion side). Only its modelDescription.xml.

VARIABLES = [  # name, causality, unit, start
    ("m", "parameter", "kg", "1"), ("k", "parameter", "N/m", "0"), ("c", "parameter", "N.s/m", "0"),
    ("kc", "parameter", "N/m", "0"), ("cc", "parameter", "N.s/m", "0"), ("x0", "parameter", "m", "0"),
    ("v0", "parameter", "m/s", "0"),
    ("x", "output", "m", None), ("v", "output", "m/s", None), ("fc", "output", "N", None), ("E", "output", "J", None),
    ("f_in", "input", "N", "0"), ("x_in", "input", "m", "0"), ("v_in", "input", "m/s", "0"),
]
QUOTE = '"'
UNITS = {"kg": {"kg": 1}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1}, "m": {"m": 1},
         "m/s": {"m": 1, "s": -1}, "N": {"kg": 1, "m": 1, "s": -2}, "J": {"kg": 1, "m": 2, "s": -2},
         "N.m": {"kg": 1, "m": 2, "s": -2}, "rad/s": {"rad": 1, "s": -1}, "rad": {"rad": 1},
         "Pa": {"kg": 1, "m": -1, "s": -2}, "m3/s": {"m": 3, "s": -1}, "m3": {"m": 3},
         "V": {"kg": 1, "m": 2, "s": -3, "A": -1}, "A": {"A": 1}, "C": {"A": 1, "s": 1}}
# the oscillator in another domain: its force, velocity and position variables in the units of an effort, a
# flow and a displacement (its parameters keep theirs: an import reads only what it couples)
DOMAIN_UNITS = {"translational": ("N", "m/s", "m"), "rotational": ("N.m", "rad/s", "rad"),
                "hydraulic": ("Pa", "m3/s", "m3"), "electrical": ("V", "A", "C")}
DOMAIN_GROUPS = {  # OSP-IS: port, effort, flow, displacement, quasi port
    "translational": ("LinearMechanicalPort", "Force", "LinearVelocity", "LinearDisplacement",
                      "LinearMechanicalQuasiPort"),
    "rotational": ("AngularMechanicalPort", "Torque", "AngularVelocity", "AngularDisplacement",
                   "AngularMechanicalQuasiPort"),
    "hydraulic": ("HydraulicPort", "Pressure", "VolumeFlowRate", "Volume", "HydraulicQuasiPort"),
    "electrical": ("ElectromagneticPort", "Voltage", "Current", "Charge", "ElectromagneticQuasiPort")}


def domain_variables(domain: str) -> list:
    effort, flow, displacement = DOMAIN_UNITS[domain]
    units = {"fc": effort, "f_in": effort, "v": flow, "v_in": flow, "v0": flow, "x": displacement,
             "x_in": displacement, "x0": displacement}
    return [(name, causality, units.get(name, unit), start) for name, causality, unit, start in VARIABLES]


def model_description(variables=VARIABLES, model_name: str = "oscillator") -> str:
    units = "".join(f'<Unit name="{name}"><BaseUnit {" ".join(f"{b}={QUOTE}{e}{QUOTE}" for b, e in dims.items())}/>'
                    "</Unit>" for name, dims in UNITS.items())
    scalars, outputs = [], []
    for index, (name, causality, unit, start) in enumerate(variables, start=1):
        variability = ' variability="fixed"' if causality == "parameter" else ""
        start_attribute = f' start="{start}"' if start is not None else ""
        scalars.append(f'<ScalarVariable name="{name}" valueReference="{index}" causality="{causality}"{variability}>'
                       f'<Real unit="{unit}"{start_attribute}/></ScalarVariable>')
        if causality == "output":
            outputs.append(f'<Unknown index="{index}"/>')
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" modelName="{model_name}" '
            f'guid="{{8c4e810f-3df3-4a00-8276-176fa3c9f000}}" numberOfEventIndicators="0">'
            f'<CoSimulation modelIdentifier="{model_name}" canGetAndSetFMUstate="true"/>'
            f"<UnitDefinitions>{units}</UnitDefinitions><ModelVariables>{''.join(scalars)}</ModelVariables>"
            f"<ModelStructure><Outputs>{''.join(outputs)}</Outputs></ModelStructure></fmiModelDescription>")


def write_fmu(path: Path, description: str | None = None) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("modelDescription.xml", description or model_description())
    return path


# OSP --------------------------------------------------------------------------------------------------

OSP_MODEL_DESCRIPTION = """<?xml version="1.0" encoding="utf-8"?>
<OspModelDescription xmlns="https://open-simulation-platform.com/OspModelDescription/1.0.0" version="1.0">
  <UnitDefinitions>
    <Unit name="N"><BaseUnit kg="1" m="1" s="-2"/></Unit>
    <Unit name="m/s"><BaseUnit m="1" s="-1"/></Unit>
    <Unit name="m"><BaseUnit m="1"/></Unit>
  </UnitDefinitions>
  <VariableGroups>
    <LinearMechanicalPort name="p1">
      <Force name="p1 force"><Variable ref="fc" unit="N"/></Force>
      <LinearVelocity name="p1 velocity"><Variable ref="v_in" unit="m/s"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearMechanicalPort name="p2">
      <Force name="p2 force"><Variable ref="f_in" unit="N"/></Force>
      <LinearVelocity name="p2 velocity"><Variable ref="v" unit="m/s"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearDisplacement name="position"><Variable ref="x" unit="m"/></LinearDisplacement>
    <LinearDisplacement name="position input"><Variable ref="x_in" unit="m"/></LinearDisplacement>
    <AngularMechanicalPort name="shaft">
      <Torque name="torque"><Variable ref="fc"/></Torque>
      <AngularVelocity name="speed"><Variable ref="v_in"/></AngularVelocity>
    </AngularMechanicalPort>
    <AngularMechanicalPort name="shaft 2">
      <Torque name="torque 2"><Variable ref="f_in"/></Torque>
      <AngularVelocity name="speed 2"><Variable ref="v"/></AngularVelocity>
    </AngularMechanicalPort>
    <LinearAcceleration name="acceleration"><Variable ref="x"/></LinearAcceleration>
    <Generic name="coefficients"><Variable ref="k"/></Generic>
  </VariableGroups>
</OspModelDescription>
"""

PORTS = """
    <VariableGroupConnection>
      <VariableGroup simulator="S1" name="p1"/>
      <VariableGroup simulator="S2" name="p2"/>
    </VariableGroupConnection>"""
POSITION = """
    <VariableConnection>
      <Variable simulator="S2" name="x"/>
      <Variable simulator="S1" name="x_in"/>
    </VariableConnection>"""
POWER_BOND = """
    <VariableConnection powerBond="c">
      <Variable simulator="S1" name="v_in" causality="input"/>
      <Variable simulator="S2" name="v" causality="output"/>
    </VariableConnection>
    <VariableConnection powerBond="c">
      <Variable simulator="S2" name="f_in" causality="input"/>
      <Variable simulator="S1" name="fc" causality="output"/>
    </VariableConnection>"""


def initial_values(**values: float) -> str:
    return "".join(f'<InitialValue variable="{name}"><Real value="{value}"/></InitialValue>'
                   for name, value in values.items())


def osp_system(connections: str = PORTS + POSITION, end: str = "<EndTime>10.0</EndTime>", base: str = "0.001",
               algorithm: str = "fixedStep", step_1: str = "0.001", source_1: str = "oscillator.fmu") -> str:
    s1 = initial_values(m=1.0, k=10.0, c=0.1, kc=100.0, cc=0.1, v0=100.0)
    s2 = initial_values(m=1.0, k=1000.0, c=0.1, v0=-100.0)
    return f"""<?xml version="1.0" encoding="utf-8"?>
<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
  <StartTime>0.0</StartTime>
  {end}
  <BaseStepSize>{base}</BaseStepSize>
  <Algorithm>{algorithm}</Algorithm>
  <Simulators>
    <Simulator name="S1" source="{source_1}" stepSize="{step_1}">
      <InitialValues>{s1}</InitialValues>
    </Simulator>
    <Simulator name="S2" source="oscillator.fmu" stepSize="0.001">
      <InitialValues>{s2}</InitialValues>
    </Simulator>
  </Simulators>
  <Connections>{connections}
  </Connections>
</OspSystemStructure>
"""


@pytest.fixture
def osp_dir(tmp_path: Path) -> Path:
    directory = tmp_path / "two_mass_damped_fmu"
    directory.mkdir()
    write_fmu(directory / "oscillator.fmu")
    (directory / "oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)
    return directory


def osp_import(directory: Path, text: str, **options) -> tuple[dict, list[str]]:
    path = directory / "OspSystemStructure.xml"
    path.write_text(text)
    return import_system(path, **options)


def line(text: str, needle: str, occurrence: int = 1) -> int:
    """The line (from 1) of the ``occurrence``-th ``needle`` in ``text``."""
    at = -1
    for _ in range(occurrence):
        at = text.index(needle, at + 1)
    return text.count("\n", 0, at) + 1


S1_ELEMENT = '<Simulator name="S1"'
S1_COMPONENT = '<ssd:Component name="S1"'


def q(text: str) -> str:
    """``text`` with its backquotes as double quotes (XML attributes in f-strings)."""
    return text.replace("`", QUOTE)


def osp_refusal(directory: Path, text: str, **options) -> dict[str, str]:
    with pytest.raises(SceneError) as caught:
        osp_import(directory, text, **options)
    assert caught.value.path == str(directory / "OspSystemStructure.xml")
    return {p.key: p.reason for p in caught.value.problems}


OSP_DESCRIPTION = "imported from the OSP system structure OspSystemStructure.xml"


def test_osp_ports_and_a_position_connection_are_the_two_mass_scene(osp_dir):
    document, notes = osp_import(osp_dir, osp_system())
    assert document == expected(OSP_DESCRIPTION)
    assert tomllib.loads(tomli_w.dumps(document)) == document
    assert "manager.duration = 10.0 s: from EndTime - StartTime" in notes
    assert any("energy = 'E'" in n for n in notes)


def test_osp_displacement_as_a_linear_displacement_group_connection(osp_dir):
    position = """
    <VariableGroupConnection>
      <VariableGroup simulator="S1" name="position input"/>
      <VariableGroup simulator="S2" name="position"/>
    </VariableGroupConnection>"""
    document, _ = osp_import(osp_dir, osp_system(PORTS + position))
    assert document == expected(OSP_DESCRIPTION)


def test_osp_power_bond_pair_names_the_coupling(osp_dir):
    """libcosim's own bond marker: a force and a velocity connection sharing a powerBond name."""
    document, _ = osp_import(osp_dir, osp_system(POWER_BOND + POSITION))
    assert document == expected(OSP_DESCRIPTION, coupling="c")


def test_osp_without_end_time_takes_the_duration_asked_for(osp_dir):
    document, notes = osp_import(osp_dir, osp_system(end=""), duration=10.0)
    assert document == expected(OSP_DESCRIPTION)
    document, notes = osp_import(osp_dir, osp_system(end=""))
    assert document["manager"]["duration"] == 10.0
    assert any("assumed" in n and "no EndTime" in n for n in notes)
    document, notes = osp_import(osp_dir, osp_system(end=""), duration=2.0004)
    assert document["manager"]["duration"] == 2.001
    assert any("rounded up" in n for n in notes)


BEYOND_64_BIT = "expected at most 9.223e+09 s (times are counted in signed 64-bit nanoseconds)"


@pytest.mark.parametrize("options, key, reason", [
    ({"end": "<EndTime>1e300</EndTime>"}, "duration", f"1e+300 s from EndTime - StartTime: {BEYOND_64_BIT}"),
    ({"base": "1e300"}, "BaseStepSize", f"base step 1e+300 s: {BEYOND_64_BIT}"),
    ({"step_1": "1e308"}, "Simulator 'S1' (line 8)", f"step size 1e+308 s: {BEYOND_64_BIT}"),
    ({"base": "5e-324"}, "BaseStepSize", "base step 5e-324 s: expected at least 1 ns (times are counted in whole "
                                         "nanoseconds)"),
])
def test_osp_times_beyond_64_bit_nanoseconds_are_refused_in_one_line(osp_dir, options, key, reason):
    """More nanoseconds than times travel as: a scene error
    naming the element, and exit status 2 from the command line."""
    assert osp_refusal(osp_dir, osp_system(**options)) == {key: reason}
    assert_one_line_error(["check", str(osp_dir / "OspSystemStructure.xml")], f"{key}: {reason}")
    assert_one_line_error(["convert", str(osp_dir / "OspSystemStructure.xml"), "--to", str(osp_dir / "scene.toml")],
                          f"{key}: {reason}")


def test_ssp_a_base_step_beyond_64_bit_nanoseconds_is_refused_in_one_line(ssp_dir):
    key, reason = "DefaultExperiment: osp:FixedStepAlgorithm baseStepSize", f"base step 1e+308 s: {BEYOND_64_BIT}"
    assert ssd_refusal(ssp_dir, ssd_system(base="1e308")) == {key: reason}
    for command in ("check", "run"):
        assert_one_line_error([command, str(ssp_dir / "SystemStructure.ssd")], f"{key}: {reason}")


def assert_one_line_error(argv: list[str], problem: str) -> None:
    """The command line, in process, exits 2 with the problem and no traceback."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        assert main(argv) == 2, errors.getvalue()
    assert problem in " ".join(errors.getvalue().split()) and "Traceback" not in errors.getvalue()


def test_osp_multi_rate_gives_communication_ratios(osp_dir):
    document, _ = osp_import(osp_dir, osp_system(base="0.0005", step_1="0.001"))
    assert document["manager"]["macro_step"] == 0.0005
    assert document["subsystems"]["S1"]["comm_ratio"] == 2 and document["subsystems"]["S2"]["comm_ratio"] == 2
    assert document["subsystems"]["S1"]["micro_step"] == 0.001


def test_osp_refuses_an_unknown_algorithm(osp_dir):
    text = osp_system(algorithm="jacobiWithRollback")
    key = f"Algorithm (line {line(text, '<Algorithm>')})"
    assert osp_refusal(osp_dir, text) == {key: "unknown algorithm 'jacobiWithRollback'; expected fixedStep"}


ECCO = {"SafetyFactor": 0.99, "StepSize": 0.0001, "MinimumStepSize": "0.00001", "MaximumStepSize": 0.01,  # libcosimpy's
        "MinimumChangeRate": 0.2, "MaximumChangeRate": 1.5, "ProportionalGain": 0.2, "IntegralGain": 0.15,  # README
        "RelativeTolerance": "1e-6", "AbsoluteTolerance": "1e-5"}


def ecco_system(parameters: dict[str, object] = ECCO) -> str:
    return osp_system(algorithm="ecco").replace("</OspSystemStructure>",
                                                ecco_configuration(parameters) + "</OspSystemStructure>")


def test_osp_ecco_imports_as_the_energy_controlled_step_with_its_parameters(osp_dir):
    """libcosim's EccoConfiguration (the README of libcosimpy's example) maps name for name; the macro-step is
    libcosim's resolution, 1 ns, and every simulator takes one step per macro-step whatever its stepSize."""
    document, notes = osp_import(osp_dir, ecco_system())
    manager = document["manager"]
    assert manager["step_control"] == "energy" and manager["macro_step"] == 1e-9
    assert manager["energy_control"] == {
        "safety_factor": 0.99, "step_size": 0.0001, "min_step_size": 0.00001, "max_step_size": 0.01,
        "min_change_rate": 0.2, "max_change_rate": 1.5, "p_gain": 0.2, "i_gain": 0.15, "rel_tolerance": 1e-6,
        "abs_tolerance": 1e-5}
    assert all("comm_ratio" not in table for table in document["subsystems"].values())
    assert any(note.startswith("manager.step_control = 'energy': the ecco algorithm") for note in notes)


def test_osp_ecco_without_its_parameters_is_refused_as_libcosim_refuses_it(osp_dir):
    text = osp_system(algorithm="ecco")
    key = f"Algorithm (line {line(text, '<Algorithm>')})"
    assert osp_refusal(osp_dir, text)[key].startswith("algorithm 'ecco' needs an EccoConfiguration element")
    text = ecco_system({**{name: value for name, value in ECCO.items() if name != "IntegralGain"},
                        "SafetyFactor": "high", "Gain": 1})
    problems = osp_refusal(osp_dir, text)
    assert problems[f"EccoConfiguration (line {line(text, '<EccoConfiguration>')})"].startswith(
        "no IntegralGain: libcosim's ecco algorithm needs every parameter")
    assert problems[f"Gain (line {line(text, '<Gain>')})"].startswith("unknown element; expected one of SafetyFactor")
    assert f"SafetyFactor (line {line(text, '<SafetyFactor>')})" in problems


def test_osp_ecco_runs_at_its_base_step_when_the_user_asks_for_the_fixed_step_algorithm(osp_dir):
    text = osp_system(algorithm="ecco")
    fixed, notes = osp_import(osp_dir, text, algorithm="fixed")
    assert fixed == osp_import(osp_dir, osp_system())[0]  # the same scene as the file with fixedStep
    assert f"Algorithm (line {line(text, '<Algorithm>')}): 'ecco' (adaptive step size) run with the fixed-step " \
           "algorithm at the base step, as asked (manager.algorithm = 'fixed')" in notes
    path = osp_dir / "OspSystemStructure.xml"
    with pytest.raises(SceneError) as caught:  # the FMUs here have no binary: the algorithm was taken, the rest not
        load_scene(str(path), ["manager.algorithm=fixed", "manager.duration=0.01"])
    assert {p.key for p in caught.value.problems} == {"subsystems.S1.fmu", "subsystems.S2.fmu"}
    with pytest.raises(SceneError) as caught:
        load_scene(str(path), ["manager.algorithm=ecco"])
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        ("manager.algorithm", "expected one of fixed, got 'ecco'")]


PLAIN_VELOCITY = """
    <VariableConnection>
      <Variable simulator="S1" name="v"/>
      <Variable simulator="S2" name="v_in"/>
    </VariableConnection>"""


def test_osp_a_connection_outside_a_bond_is_a_signal_coupling(osp_dir):
    """A displacement no bond uses and a velocity without powerBond: each a signal coupling named after its
    output, the input receiving the value unchanged; the subsystems need no points."""
    text = osp_system(POSITION + PLAIN_VELOCITY)
    document, notes = osp_import(osp_dir, text)
    assert document["couplings"] == {
        "S2_x": {"type": "signal", "output": "S2.x", "input": "S1.x_in"},
        "S1_v": {"type": "signal", "output": "S1.v", "input": "S2.v_in"}}
    assert document["outputs"]["signals"] == ["S2_x", "S1_v"]
    for name in ("S1", "S2"):
        assert "points" not in document["subsystems"][name] and "outputs" not in document["subsystems"][name]
    velocity = f"VariableConnection (line {line(text, '<VariableConnection>', 2)})"
    assert f"{velocity}: S1.v -> S2.v_in (velocity) has no powerBond: a signal coupling, whose power zencosim " \
           "does not monitor (mark the effort and the flow connection of a bond, e.g. its force and its velocity, " \
           "with one powerBond name to make them a power bond)" in notes
    assert f"couplings.S1_v: a signal coupling, S1.v -> S2.v_in ({velocity})" in notes
    assert tomllib.loads(tomli_w.dumps(document)) == document


def test_osp_one_output_feeding_two_inputs_gives_two_signals_named_uniquely(osp_dir):
    """The second is numbered; an FMU may feed its own input."""
    own = PLAIN_VELOCITY.replace('simulator="S2" name="v_in"', 'simulator="S1" name="v_in"')
    document, _ = osp_import(osp_dir, osp_system(POSITION + PLAIN_VELOCITY + own))
    assert document["couplings"] == {
        "S2_x": {"type": "signal", "output": "S2.x", "input": "S1.x_in"},
        "S1_v": {"type": "signal", "output": "S1.v", "input": "S2.v_in"},
        "S1_v_2": {"type": "signal", "output": "S1.v", "input": "S1.v_in"}}


def test_osp_still_refuses_an_input_connected_twice_and_functions(osp_dir):
    twice = PLAIN_VELOCITY.replace('simulator="S1" name="v"', 'simulator="S2" name="v"')
    text = osp_system(POSITION + PLAIN_VELOCITY + twice).replace("<Connections>", """<Functions>
    <LinearTransformation name="negate" factor="-1" offset="0"/>
  </Functions>
  <Connections>""")
    problems = osp_refusal(osp_dir, text)
    first, second = (f"VariableConnection (line {line(text, '<VariableConnection>', i)})" for i in (2, 3))
    assert problems == {
        f"LinearTransformation 'negate' (line {line(text, '<LinearTransformation')})":
            "OSP functions (LinearTransformation, Sum, VectorSum) are not supported: zencosim has no function blocks; "
            "connect the simulators' variables directly",
        second: f"input S2.v_in is already connected by {first}"}


def test_osp_refuses_a_connection_of_integer_variables(tmp_path):
    description = model_description().replace('<Real unit="m" start="0"/></ScalarVariable>',
                                              '<Integer start="0"/></ScalarVariable>', 1)  # x0 an Integer
    description = description.replace('name="x0" valueReference="6" causality="parameter" variability="fixed"',
                                      'name="x0" valueReference="6" causality="input"')
    write_fmu(tmp_path / "oscillator.fmu", description)
    (tmp_path / "oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)
    text = osp_system(PORTS + POSITION + PLAIN_VELOCITY.replace('name="v_in"', 'name="x0"'))
    problems = osp_refusal(tmp_path, text)
    assert problems == {f"VariableConnection (line {line(text, '<VariableConnection>', 2)})":
                        "S2.x0 is Integer: zencosim exchanges Real variables only (Integer, Boolean, Enumeration and "
                        "String connections are not exchanged yet)"}


def test_osp_refuses_a_missing_fmu_file(osp_dir):
    text = osp_system(source_1="missing.fmu")
    problems = osp_refusal(osp_dir, text)
    assert problems == {f"Simulator 'S1' (line {line(text, S1_ELEMENT)})":
                        f"source 'missing.fmu': no FMU file at {osp_dir / 'missing.fmu'}"}


def test_osp_refuses_a_step_size_that_does_not_divide_into_the_base_step(osp_dir):
    text = osp_system(step_1="0.0015")
    assert osp_refusal(osp_dir, text) == {
        f"Simulator 'S1' (line {line(text, S1_ELEMENT)})":
            "step size 0.0015 s is not a whole multiple of the base step 0.001 s: zencosim communicates every whole "
            "number of base steps"}


def group_connection(a: str, b: str) -> str:
    return f"""
    <VariableGroupConnection>
      <VariableGroup simulator="S1" name="{a}"/>
      <VariableGroup simulator="S2" name="{b}"/>
    </VariableGroupConnection>"""


def test_osp_refuses_unknown_group_types_and_a_port_of_another_domains_variables(osp_dir):
    """An AngularMechanicalPort whose Torque and AngularVelocity are the oscillator's force [N] and velocity
    [m/s]: a port of mixed domains, refused naming both."""
    text = osp_system(group_connection("shaft", "shaft 2") + group_connection("acceleration", "acceleration"))
    with pytest.raises(SceneError) as caught:
        osp_import(osp_dir, text)
    shaft, acceleration = (f"VariableGroupConnection (line {line(text, '<VariableGroupConnection>', i)})"
                           for i in (1, 2))
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        (shaft, "the Torque of S1.shaft (AngularMechanicalPort, rotational) is in units of force; expected N.m "
                "(torque)"),
        (shaft, "the AngularVelocity of S1.shaft (AngularMechanicalPort, rotational) is in units of velocity; "
                "expected rad/s (angular_velocity)"),
        (acceleration, "variable group type LinearAcceleration (S1.acceleration) is not supported: zencosim couples "
                       "the OSP-IS ports (LinearMechanicalPort, AngularMechanicalPort, HydraulicPort, "
                       "ElectromagneticPort, their quasi ports), the groups of one quantity in them and Generic "
                       "groups; see docs/system-imports.md")]


def test_osp_a_port_without_displacement_is_a_bond_that_exchanges_none(osp_dir):
    """A LinearMechanicalPort exchanges force and velocity; with no displacement connected the coupling's
    displacement is [] (the force side receives the velocity alone; its x_in keeps its start value, as in
    libcosim), and the velocity is recorded in its place."""
    text = osp_system(PORTS)
    document, notes = osp_import(osp_dir, text)
    want = expected(OSP_DESCRIPTION)
    del want["subsystems"]["S1"]["points"]["p1"]["position_input"], want["subsystems"]["S2"]["points"]["p2"]["position"]
    want["couplings"]["c1"]["displacement"] = []
    want["outputs"]["signals"] = ["c1.v", "c1.f"]
    assert document == want
    assert "couplings.c1.displacement = []: an OSP LinearMechanicalPort exchanges no displacement, and no " \
           "displacement connection joins it; S1 receives the velocity alone (an input of it that no connection " \
           "feeds keeps its start value, as in libcosim)" in notes
    assert tomllib.loads(tomli_w.dumps(document)) == document


def domain_osp_description(domain: str) -> str:
    port, effort, flow, displacement, quasi = DOMAIN_GROUPS[domain]
    return f"""<?xml version="1.0" encoding="utf-8"?>
<OspModelDescription xmlns="https://open-simulation-platform.com/OspModelDescription/1.0.0" version="1.0">
  <VariableGroups>
    <{port} name="p1">
      <{effort} name="p1 effort"><Variable ref="fc"/></{effort}>
      <{flow} name="p1 flow"><Variable ref="v_in"/></{flow}>
    </{port}>
    <{port} name="p2">
      <{effort} name="p2 effort"><Variable ref="f_in"/></{effort}>
      <{flow} name="p2 flow"><Variable ref="v"/></{flow}>
    </{port}>
    <{displacement} name="position"><Variable ref="x"/></{displacement}>
    <{displacement} name="position input"><Variable ref="x_in"/></{displacement}>
    <{quasi} name="q1">
      <{effort} name="q1 effort"><Variable ref="fc"/></{effort}>
      <{displacement} name="q1 displacement"><Variable ref="x_in"/></{displacement}>
    </{quasi}>
    <{quasi} name="q2">
      <{effort} name="q2 effort"><Variable ref="f_in"/></{effort}>
      <{displacement} name="q2 displacement"><Variable ref="x"/></{displacement}>
    </{quasi}>
    <{flow} name="flow"><Variable ref="v"/></{flow}>
    <{flow} name="flow input"><Variable ref="v_in"/></{flow}>
  </VariableGroups>
</OspModelDescription>
"""


@pytest.fixture(params=list(DOMAIN_UNITS))
def domain_dir(request, tmp_path: Path) -> tuple[str, Path]:
    directory = tmp_path / "two_mass_damped_fmu"
    directory.mkdir()
    write_fmu(directory / "oscillator.fmu", model_description(domain_variables(request.param)))
    (directory / "oscillator_OspModelDescription.xml").write_text(domain_osp_description(request.param))
    return request.param, directory


def expected_in(domain: str, description: str, coupling: str = "c1", points: tuple[str, str] = ("p1", "p2")) -> dict:
    """The two-mass scene with its bond in ``domain``: ``domain`` keys on the points and the coupling."""
    want = expected(description, coupling)
    for name, point, old in (("S1", points[0], "p1"), ("S2", points[1], "p2")):
        table = want["subsystems"][name]["points"].pop(old)
        want["subsystems"][name]["points"][point] = table
        want["couplings"][coupling][f"{'force' if name == 'S1' else 'motion'}_side"] = f"{name}.{point}"
        if domain != "translational":
            table["domain"] = domain
    if domain != "translational":
        want["couplings"][coupling]["domain"] = domain
    return want


def test_osp_ports_of_every_domain_are_bonds_of_that_domain(domain_dir):
    domain, directory = domain_dir
    document, notes = osp_import(directory, osp_system(PORTS + group_connection("position input", "position")))
    assert document == expected_in(domain, OSP_DESCRIPTION)
    assert document["subsystems"]["S1"]["energy"] == "E"  # a torque in N.m is not an energy
    assert tomllib.loads(tomli_w.dumps(document)) == document
    assert domain == "translational" or any(n.startswith(f"couplings.c1.domain = {domain!r}") for n in notes)


def test_osp_power_bond_pairs_of_every_domain_by_their_units(domain_dir):
    """libcosim's powerBond marker on plain connections: the units say the domain (N.m and rad/s, Pa and m3/s,
    V and A); the displacement (rad, m3, C) joins the bond of its domain."""
    domain, directory = domain_dir
    document, _ = osp_import(directory, osp_system(POWER_BOND + POSITION))
    assert document == expected_in(domain, OSP_DESCRIPTION, coupling="c", points=("p1", "p2"))


def test_osp_a_quasi_port_with_its_flow_connected_is_a_bond(domain_dir):
    """A quasi port exchanges the effort and the displacement; the flow (a flow group, or a plain connection)
    between the same two simulators, motion side to force side, completes the bond."""
    domain, directory = domain_dir
    text = osp_system(group_connection("q1", "q2") + group_connection("flow input", "flow"))
    document, notes = osp_import(directory, text)
    assert document == expected_in(domain, OSP_DESCRIPTION, points=("q1", "q2"))
    plain_flow = PLAIN_VELOCITY.replace('"S1" name="v"', '"S2" name="v"')
    plain_flow = plain_flow.replace('"S2" name="v_in"', '"S1" name="v_in"')
    document, _ = osp_import(directory, osp_system(group_connection("q1", "q2") + plain_flow))
    assert document == expected_in(domain, OSP_DESCRIPTION, points=("q1", "q2"))
    _, flow, _, _, quasi = DOMAIN_GROUPS[domain]
    assert any(n.startswith(f"VariableGroupConnection (line {line(text, '<VariableGroupConnection>')}): the {quasi} "
                            "exchanges the") for n in notes)


def test_osp_a_quasi_port_without_its_flow_is_refused_naming_why(domain_dir):
    domain, directory = domain_dir
    port, _, flow_group, _, quasi = DOMAIN_GROUPS[domain]
    effort, flow, displacement = {"translational": ("force", "velocity", "displacement"),
                                  "rotational": ("torque", "angular velocity", "angle"),
                                  "hydraulic": ("pressure", "volume flow", "volume"),
                                  "electrical": ("voltage", "current", "charge")}[domain]
    text = osp_system(group_connection("q1", "q2"))
    problems = osp_refusal(directory, text)
    assert problems == {f"VariableGroupConnection (line {line(text, '<VariableGroupConnection>')})":
                        f"{quasi} S1.q1 -> S2.q2: a quasi port exchanges the {effort} and the {displacement} but no "
                        f"{flow}; zencosim's power bond needs the {flow} (its residual power is {effort} x {flow}): "
                        f"connect the {flow} output of S2 to S1 too ({'an' if flow_group[0] == 'A' else 'a'} "
                        f"{flow_group} group or a variable connection), or use "
                        f"{'an' if port[0] in 'AE' else 'a'} {port}"}


def test_osp_a_power_bond_of_two_domains_is_refused(osp_dir, tmp_path):
    """A torque [N.m] marked as one bond with a velocity [m/s]: no domain has both."""
    write_fmu(osp_dir / "oscillator.fmu", model_description([
        (n, c, "N.m" if n in ("fc", "f_in") else u, s) for n, c, u, s in VARIABLES]))
    text = osp_system(POWER_BOND + POSITION)
    problems = osp_refusal(osp_dir, text)
    (reason,) = problems.values()
    assert reason.startswith("powerBond 'c': expected one effort and one flow connection of one domain (force and "
                             "velocity, torque and angular velocity, pressure and volume flow, or voltage and current, "
                             "by the units of their variables), and its displacement connections if any, got "
                             "S2.v -> S1.v_in (velocity), S1.fc -> S2.f_in (torque)"), reason


def test_ssd_the_bond_rule_holds_in_every_domain_and_without_displacement(domain_dir):
    """SSP: an effort output of S1 to S2 and a flow output of S2 to S1, of one domain by their units, are a bond
    of that domain; the displacement is optional."""
    domain, directory = domain_dir
    description = "imported from the SSP SystemStructure.ssd"
    document, _ = ssd_import(directory, ssd_system())
    assert document == expected_in(domain, description)
    without = "\n".join(SSP_CONNECTIONS.splitlines()[:-1])  # no displacement connection
    document, notes = ssd_import(directory, ssd_system(without))
    want = expected_in(domain, description)
    del want["subsystems"]["S1"]["points"]["p1"]["position_input"], want["subsystems"]["S2"]["points"]["p2"]["position"]
    want["couplings"]["c1"]["displacement"] = []
    want["outputs"]["signals"] = ["c1.v", "c1.f"]
    assert document == want
    assert any(n.startswith("couplings.c1.displacement = []: no ") for n in notes)


def test_osp_a_simulator_coupled_to_nothing_runs_free_and_publishes_its_outputs(osp_dir):
    text = osp_system().replace("</Simulators>", '<Simulator name="S3" source="oscillator.fmu"/>\n  </Simulators>')
    document, notes = osp_import(osp_dir, text)
    assert document["subsystems"]["S3"] == {"model": "fmu", "fmu": "oscillator.fmu", "micro_step": 0.001,
                                            "energy": "E", "outputs": "all"}
    assert "outputs" not in document["subsystems"]["S1"]  # a coupled one publishes what its couplings send
    assert f"subsystems.S3.outputs = 'all': Simulator 'S3' (line {line(text, q('name=`S3`'))}) is coupled to " \
           "nothing; it runs free and publishes every output variable as a signal of its name" in notes


@pytest.mark.skipif(shutil.which("gcc") is None, reason="building the example FMU needs gcc")
def test_imported_scenes_load_with_the_example_fmu(tmp_path):
    """With a real FMU (zencosim's example oscillator, built but not run) the imported documents are scenes
    that zencosim loads: model "fmu", points, start values and energy as the FMU model reads them."""
    from zencosim.examples.fmus.build import build_fmu

    build_fmu(tmp_path / "oscillator.fmu", 2, ("cs",))
    (tmp_path / "zencosim oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)  # its modelName
    for name, text in (("OspSystemStructure.xml", osp_system()), ("SystemStructure.ssd", ssd_system())):
        path = tmp_path / name
        path.write_text(text)
        document, _ = import_system(path)
        scene = scene_from_text(tomli_w.dumps(document), str(tmp_path / "scene.toml"))
        assert scene.subsystems["S1"].spec.start == {"m": 1.0, "k": 10.0, "c": 0.1, "kc": 100.0, "cc": 0.1, "v0": 100.0}
        assert scene.subsystems["S2"].spec.energy == "E"
        assert sorted(scene.couplings) == ["c1"] and scene.manager.duration == 10.0


# SSP --------------------------------------------------------------------------------------------------

def parameter_set(**values: float) -> str:
    parameters = "".join(f'<ssv:Parameter name="{n}"><ssv:Real value="{v}"/></ssv:Parameter>'
                         for n, v in values.items())
    return (f'<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" '
            f'name="start"><ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
            f"</ssd:ParameterBinding></ssd:ParameterBindings>")


SSP_CONNECTIONS = """
      <ssd:Connection startElement="S1" startConnector="fc" endElement="S2" endConnector="f_in"/>
      <ssd:Connection startElement="S2" startConnector="v" endElement="S1" endConnector="v_in"/>
      <ssd:Connection startElement="S2" startConnector="x" endElement="S1" endConnector="x_in"/>"""


def ssd_system(connections: str = SSP_CONNECTIONS, source: str = "oscillator.fmu",
               experiment: str = 'startTime="0" stopTime="10"', base: str = "0.001") -> str:
    connectors = "".join(f'<ssd:Connector name="{n}" kind="{c}"/>' for n, c, _, _ in VARIABLES if c != "parameter")
    s1 = parameter_set(m=1.0, k=10.0, c=0.1, kc=100.0, cc=0.1, v0=100.0)
    s2 = parameter_set(m=1.0, k=1000.0, c=0.1, v0=-100.0)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription name="two_mass_damped_fmu" version="1.0"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">
  <ssd:System name="two_mass">
    <ssd:Elements>
      <ssd:Component name="S1" source="{source}">
        <ssd:Connectors>{connectors}</ssd:Connectors>{s1}
      </ssd:Component>
      <ssd:Component name="S2" source="{source}">
        <ssd:Connectors>{connectors}</ssd:Connectors>{s2}
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>{connections}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment {experiment}>
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{base}"/></osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


@pytest.fixture
def ssp_dir(tmp_path: Path) -> Path:
    directory = tmp_path / "ssp"
    directory.mkdir()
    write_fmu(directory / "oscillator.fmu")
    return directory


def ssd_import(directory: Path, text: str, **options) -> tuple[dict, list[str]]:
    path = directory / "SystemStructure.ssd"
    path.write_text(text)
    return import_system(path, **options)


def ssd_refusal(directory: Path, text: str) -> dict[str, str]:
    with pytest.raises(SceneError) as caught:
        ssd_import(directory, text)
    assert caught.value.path == str(directory / "SystemStructure.ssd")
    return {p.key: p.reason for p in caught.value.problems}


def test_ssd_three_connections_are_the_two_mass_scene(ssp_dir):
    document, notes = ssd_import(ssp_dir, ssd_system())
    assert document == expected("imported from the SSP SystemStructure.ssd")
    assert "manager.duration = 10.0 s: from DefaultExperiment stopTime - startTime" in notes


def test_ssp_archive_reads_its_fmu_inside_and_says_where_to_unpack_it(tmp_path):
    path = tmp_path / "two_mass.ssp"
    fmu = write_fmu(tmp_path / "built.fmu")
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd_system(source="resources/oscillator.fmu"))
        archive.write(fmu, "resources/oscillator.fmu")
    document, notes = import_system(path)
    assert document == expected("imported from the SSP two_mass.ssp", fmu="two_mass/resources/oscillator.fmu")
    assert ("subsystems.S1.fmu = 'two_mass/resources/oscillator.fmu': the FMU is resources/oscillator.fmu inside "
            "two_mass.ssp; unpack the archive beside the scene (unzip two_mass.ssp -d two_mass)") in notes


def test_ssd_a_connection_outside_a_bond_is_a_signal_coupling(ssp_dir):
    """S1.v -> S2.v_in: a velocity with no force back (no bond S2 -> S1), a signal; the bond stays."""
    text = ssd_system(SSP_CONNECTIONS + """
      <ssd:Connection startElement="S1" startConnector="v" endElement="S2" endConnector="v_in"/>""")
    key = f"Connection S1.v -> S2.v_in (line {line(text, q('startConnector=`v` endElement=`S2`'))})"
    document, notes = ssd_import(ssp_dir, text)
    assert document["couplings"]["S1_v"] == {"type": "signal", "output": "S1.v", "input": "S2.v_in"}
    assert document["couplings"]["c1"] == expected("")["couplings"]["c1"]
    assert document["outputs"]["signals"] == ["c1.x", "c1.f", "S1_v"]
    assert f"{key}: connections between S2 and S1 form no power bond (0 force [N] S2 -> S1, 1 velocity [m/s] and 0 " \
           "displacement [m] S1 -> S2; a bond has as many of each, or no displacement): signal couplings, whose " \
           "power zencosim does not monitor" in notes


def transformed(connection: str, transformation: str) -> str:
    """``SSP_CONNECTIONS`` with ``transformation`` inside the connection from ``connection`` (its start)."""
    start = f'startConnector="{connection}"'
    head, tail = SSP_CONNECTIONS.split(start)
    end = tail.index("/>")
    return head + start + tail[:end] + f">{transformation}</ssd:Connection>" + tail[end + 2:]


def test_ssd_linear_transformation_of_a_bonds_force_is_its_force_factor(ssp_dir):
    document, notes = ssd_import(ssp_dir, ssd_system(transformed("fc", '<ssc:LinearTransformation factor="-1"/>')))
    assert document["couplings"]["c1"]["force_factor"] == -1.0
    del document["couplings"]["c1"]["force_factor"]
    assert document == expected("imported from the SSP SystemStructure.ssd")
    assert any(n.startswith("couplings.c1.force_factor = -1.0: the transformation of its force connection")
               for n in notes)


def test_ssd_linear_transformation_of_a_signal_is_its_factor_and_offset(ssp_dir):
    text = ssd_system(SSP_CONNECTIONS + """
      <ssd:Connection startElement="S1" startConnector="v" endElement="S2" endConnector="v_in">
        <ssc:LinearTransformation factor="2.5" offset="-0.5"/></ssd:Connection>""")
    document, _ = ssd_import(ssp_dir, text)
    assert document["couplings"]["S1_v"] == {"type": "signal", "output": "S1.v", "input": "S2.v_in", "factor": 2.5,
                                             "offset": -0.5}


@pytest.mark.parametrize("connection, transformation, reason", [
    ("fc", '<ssc:LinearTransformation factor="-1" offset="2"/>',
     "LinearTransformation offset 2 on the force of a power bond: a bond's force has no offset (a factor is its "
     "force_factor)"),
    ("v", '<ssc:LinearTransformation factor="-1"/>',
     "LinearTransformation (factor -1, offset 0) on the velocity of a power bond: zencosim copies a bond's velocity "
     "and displacement unchanged (only its force may be scaled, force_factor)"),
    ("x", '<ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
          "</ssc:BooleanMappingTransformation>",
     "BooleanMappingTransformation: zencosim exchanges Real variables only (Boolean, Integer and Enumeration "
     "connections are not exchanged yet)"),
    ("x", '<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="2"/></ssc:IntegerMappingTransformation>',
     "IntegerMappingTransformation: zencosim exchanges Real variables only (Boolean, Integer and Enumeration "
     "connections are not exchanged yet)"),
])
def test_ssd_refuses_what_a_transformation_cannot_be(ssp_dir, connection, transformation, reason):
    text = ssd_system(transformed(connection, transformation))
    problems = ssd_refusal(ssp_dir, text)
    assert list(problems.values()) == [reason], problems
    (key,) = problems
    assert key.startswith(f"Connection S{2 if connection != 'fc' else 1}.{connection} -> ")


def test_ssd_a_component_coupled_to_nothing_runs_free(ssp_dir):
    text = ssd_system(connections="").replace("<ssd:Connections>\n    </ssd:Connections>", "")
    document, _ = ssd_import(ssp_dir, text)
    assert document["couplings"] == {} and document["outputs"]["signals"] == []
    assert {s["outputs"] for s in document["subsystems"].values()} == {"all"}


def test_ssd_refuses_a_connection_of_another_quantity(ssp_dir):
    text = ssd_system(SSP_CONNECTIONS.replace('startConnector="x"', 'startConnector="E"'))
    problems = ssd_refusal(ssp_dir, text)
    assert problems[f"Connection S2.E -> S1.x_in (line {line(text, q('startConnector=`E`'))})"] == (
        "connects variables of different quantities: displacement, energy")


def test_ssd_refuses_a_missing_fmu_file(ssp_dir):
    text = ssd_system(source="resources/oscillator.fmu")
    problems = ssd_refusal(ssp_dir, text)
    assert problems == {f"Component {name!r} (line {line(text, q(f'<ssd:Component name=`{name}`'))})":
                        f"source 'resources/oscillator.fmu': no FMU file at {ssp_dir / 'resources' / 'oscillator.fmu'}"
                        for name in ("S1", "S2")}


def test_ssd_refuses_a_step_size_that_does_not_divide_into_the_base_step(ssp_dir):
    hint = ('<ssd:Annotations><ssc:Annotation type="com.opensimulationplatform"><osp:StepSizeHint value="0.0025"/>'
            "</ssc:Annotation></ssd:Annotations>\n      </ssd:Component>")
    text = ssd_system().replace("</ssd:Component>", hint, 1)
    assert ssd_refusal(ssp_dir, text) == {
        f"Component 'S1' (line {line(text, S1_COMPONENT)})":
            "step size 0.0025 s is not a whole multiple of the base step 0.001 s: zencosim communicates every whole "
            "number of base steps"}
    document, _ = ssd_import(ssp_dir, text.replace("0.0025", "0.002"))
    assert document["subsystems"]["S1"]["comm_ratio"] == 2 and document["subsystems"]["S1"]["micro_step"] == 0.002
    assert document["manager"]["duration"] == 10.0


def test_ssd_refuses_an_algorithm_other_than_fixed_step(ssp_dir):
    text = ssd_system().replace('<osp:FixedStepAlgorithm baseStepSize="0.001"/>', '<osp:EccoAlgorithm/>')
    problems = ssd_refusal(ssp_dir, text)
    assert problems == {f"Algorithm (line {line(text, '<osp:Algorithm>')})":
                        "OSP algorithm: expected FixedStepAlgorithm; zencosim steps at a fixed macro step"}


def test_ssd_without_a_step_size_is_refused(ssp_dir):
    text = ssd_system().replace('<osp:FixedStepAlgorithm baseStepSize="0.001"/>', "")
    text = text.replace("<osp:Algorithm></osp:Algorithm>", "")
    problems = ssd_refusal(ssp_dir, text)
    (reason,) = problems.values()
    assert reason.startswith("no step size for S1, S2: add the OSP annotation libcosim reads")


def millimetre_fmu(path: Path) -> Path:
    """The oscillator FMU whose position output x is in mm (a unit definition with factor 0.001)."""
    description = model_description().replace("<UnitDefinitions>", '<UnitDefinitions><Unit name="mm">'
                                              '<BaseUnit m="1" factor="0.001"/></Unit>')
    return write_fmu(path, description.replace('name="x" valueReference="8" causality="output"><Real unit="m"',
                                               'name="x" valueReference="8" causality="output"><Real unit="mm"'))


def test_ssd_an_fmu_unit_with_a_factor_is_converted_at_its_boundary(ssp_dir):
    """x in mm: still the displacement of the bond (zencosim converts mm to m where the FMU outputs it)."""
    millimetre_fmu(ssp_dir / "oscillator.fmu")
    document, _ = ssd_import(ssp_dir, ssd_system())
    assert document == expected("imported from the SSP SystemStructure.ssd")


def test_ssd_refuses_a_transformation_offset_where_an_end_is_converted(ssp_dir):
    millimetre_fmu(ssp_dir / "oscillator.fmu")
    text = ssd_system(SSP_CONNECTIONS + """
      <ssd:Connection startElement="S1" startConnector="x" endElement="S2" endConnector="x_in">
        <ssc:LinearTransformation factor="1" offset="5"/></ssd:Connection>""")
    (reason,) = ssd_refusal(ssp_dir, text).values()
    assert reason.startswith("S1.x -> S2.x_in (displacement): a transformation (factor 1, offset 5) between variables "
                             "whose units are not SI, one of them with an offset")


def test_ssd_a_parameter_in_a_unit_with_a_factor_is_given_in_si(ssp_dir):
    units = '<ssd:Units><ssc:Unit name="mm"><ssc:BaseUnit m="1" factor="0.001"/></ssc:Unit></ssd:Units>'
    text = ssd_system().replace('<ssv:Parameter name="v0"><ssv:Real value="100.0"/>',
                                '<ssv:Parameter name="x0"><ssv:Real value="25" unit="mm"/></ssv:Parameter>'
                                '<ssv:Parameter name="v0"><ssv:Real value="100.0"/>')
    text = text.replace("<ssd:DefaultExperiment", units + "\n  <ssd:DefaultExperiment")
    document, notes = ssd_import(ssp_dir, text)
    assert document["subsystems"]["S1"]["start"]["x0"] == 0.025
    assert any("parameter 'x0' = 25 mm is 0.025 in SI (factor 0.001, offset 0)" in n for n in notes)


def test_osp_refuses_a_unit_with_a_factor_the_fmu_does_not_declare(osp_dir):
    """The OSP model description says x is in mm; the FMU says m: zencosim converts the FMU's units only."""
    (osp_dir / "oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION.replace(
        '<Unit name="m"><BaseUnit m="1"/></Unit>', '<Unit name="m"><BaseUnit m="1"/></Unit><Unit name="mm">'
        '<BaseUnit m="1" factor="0.001"/></Unit>').replace('<Variable ref="x" unit="m"/>',
                                                            '<Variable ref="x" unit="mm"/>'))
    position = """
    <VariableGroupConnection>
      <VariableGroup simulator="S1" name="position input"/>
      <VariableGroup simulator="S2" name="position"/>
    </VariableGroupConnection>"""
    (reason,) = osp_refusal(osp_dir, osp_system(PORTS + position)).values()
    assert reason == ("S2.x: unit 'mm' is not SI (factor 0.001, offset 0) and the FMU does not declare it for this "
                      "variable: zencosim converts the units an FMU defines for its own variables, at its boundary; "
                      "declare it in the FMU or give an SI unit")
    millimetre_fmu(osp_dir / "oscillator.fmu")  # the FMU's own unit: accepted
    document, _ = osp_import(osp_dir, osp_system(PORTS + position))
    assert document == expected(OSP_DESCRIPTION)


# vectors, names ------------------------------------------------------------------------------------

PLANAR = [("fx", "output", "N", None), ("fy", "output", "N", None), ("x", "output", "m", None),
          ("y", "output", "m", None), ("vx", "output", "m/s", None), ("vy", "output", "m/s", None)] + [
    (f"{name}_in", "input", unit, "0") for name, unit in (("fx", "N"), ("fy", "N"), ("x", "m"), ("y", "m"),
                                                          ("vx", "m/s"), ("vy", "m/s"))]
PLANAR_OSP = """<OspModelDescription xmlns="http://opensimulationplatform.com/MSMI/OSPModelDescription" version="0.1">
  <VariableGroups>
    <LinearMechanicalPort name="force port">
      <Force name="f"><Variable ref="fx"/><Variable ref="fy"/></Force>
      <LinearVelocity name="v in"><Variable ref="vx_in"/><Variable ref="vy_in"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearMechanicalPort name="motion port">
      <Force name="f in"><Variable ref="fx_in"/><Variable ref="fy_in"/></Force>
      <LinearVelocity name="v"><Variable ref="vx"/><Variable ref="vy"/></LinearVelocity>
    </LinearMechanicalPort>
    <LinearDisplacement name="position"><Variable ref="x"/><Variable ref="y"/></LinearDisplacement>
    <LinearDisplacement name="position in"><Variable ref="x_in"/><Variable ref="y_in"/></LinearDisplacement>
  </VariableGroups>
</OspModelDescription>"""


def test_osp_vector_ports_give_component_lists(tmp_path):
    write_fmu(tmp_path / "planar.fmu", model_description(PLANAR, "planar"))
    (tmp_path / "planar_OspModelDescription.xml").write_text(PLANAR_OSP)
    text = """<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
      <BaseStepSize>0.002</BaseStepSize>
      <Simulators>
        <Simulator name="arm" source="planar.fmu"/>
        <Simulator name="load 1" source="planar.fmu" stepSize="0.004"/>
      </Simulators>
      <Connections>
        <VariableGroupConnection>
          <VariableGroup simulator="load 1" name="motion port"/><VariableGroup simulator="arm" name="force port"/>
        </VariableGroupConnection>
        <VariableGroupConnection>
          <VariableGroup simulator="load 1" name="position"/><VariableGroup simulator="arm" name="position in"/>
        </VariableGroupConnection>
      </Connections>
    </OspSystemStructure>"""
    path = tmp_path / "crane.xml"
    path.write_text(text)
    document, notes = import_system(path, duration=1.003)
    assert document["name"] == "crane"
    assert document["manager"] == {"duration": 1.004, "macro_step": 0.002}
    assert document["couplings"] == {"c1": {
        "type": "force_displacement", "force_side": "arm.force_port", "motion_side": "load_1.motion_port",
        "force": ["c1.f_x", "c1.f_y"], "displacement": ["c1.x_x", "c1.x_y"], "velocity": ["c1.v_x", "c1.v_y"]}}
    assert document["subsystems"]["arm"] == {
        "model": "fmu", "fmu": "planar.fmu", "micro_step": 0.002,
        "points": {"force_port": {"force": ["fx", "fy"], "position_input": ["x_in", "y_in"],
                                  "velocity_input": ["vx_in", "vy_in"]}}}
    assert document["subsystems"]["load_1"]["comm_ratio"] == 2
    assert document["subsystems"]["load_1"]["points"] == {
        "motion_port": {"force_input": ["fx_in", "fy_in"], "position": ["x", "y"], "velocity": ["vx", "vy"]}}
    assert document["outputs"]["signals"] == ["c1.x_x", "c1.x_y", "c1.f_x", "c1.f_y"]
    assert "the simulator 'load 1' is 'load_1' in the scene (names are letters, digits, '_' and '-', unique)" in notes
    assert any(n.startswith("manager.duration = 1.004 s: from the duration asked for (1.003 s rounded up") for n in notes)
    assert any(n.startswith("subsystems.arm.micro_step = 0.002 s: Simulator 'arm'") for n in notes)
    assert "subsystems.arm: no energy (the FMU has no output in J); residual power is still monitored at its bonds" \
        in notes


# malformed input: a SceneError naming the file, never a traceback -------------------------------------

def test_import_system_refuses_other_files(tmp_path):
    with pytest.raises(SceneError) as caught:
        import_system(tmp_path / "scene.json")
    assert "expected an OSP system structure (.xml) or an SSP system (.ssp, .ssd)" in str(caught.value)


def test_a_truncated_osp_file_is_a_scene_error(osp_dir):
    text = osp_system()
    problems = osp_refusal(osp_dir, text[:300])
    assert list(problems) == ["OspSystemStructure.xml"]
    assert problems["OspSystemStructure.xml"].startswith("not well-formed XML: ")
    for cut in range(0, len(text) - 1, 23):
        osp_refusal(osp_dir, text[:cut])


def test_a_file_that_is_not_an_archive_is_a_scene_error(tmp_path):
    (tmp_path / "broken.ssp").write_text("not a zip")
    with pytest.raises(SceneError) as caught:
        import_system(tmp_path / "broken.ssp")
    assert caught.value.path == str(tmp_path / "broken.ssp")
    assert caught.value.problems[0].reason.startswith("not an SSP archive (a zip file)")


PIECES = ["<", ">", "/>", '"', "=", " ", "\n", "0", "-1", "1e-9", "nan", "inf", "&amp;", "S1", "S2", "S3", "x", "fc",
          "Force", "Generic", "Real", "Integer", "name", "simulator", "../", "file:", "http:", "<Variable/>",
          "</Connections>", "<InitialValues/>", 'powerBond="c"', 'causality="output"']


def mutated(data, text: str) -> str:
    """``text`` after one to three edits: a cut, a deletion, an insertion, a line dropped, doubled or swapped."""
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        if not text:
            break
        lines = text.split("\n")
        at = data.draw(st.integers(0, len(text) - 1), label="at")
        edit = data.draw(st.sampled_from(["cut", "delete", "insert", "drop", "double", "swap"]), label="edit")
        if edit == "cut":
            text = text[:at]
        elif edit == "delete":
            text = text[:at] + text[at + data.draw(st.integers(1, 12), label="length"):]
        elif edit == "insert":
            text = text[:at] + data.draw(st.sampled_from(PIECES), label="piece") + text[at:]
        else:
            i, j = (data.draw(st.integers(0, len(lines) - 1), label="line") for _ in range(2))
            if edit == "drop":
                del lines[i]
            elif edit == "double":
                lines.insert(i, lines[j])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
    return text


MUTATIONS = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@MUTATIONS
@given(data=st.data())
def test_a_mutated_osp_file_is_imported_or_a_scene_error(osp_dir, data):
    connections = data.draw(st.sampled_from([PORTS + POSITION, POWER_BOND + POSITION]), label="bond")
    try:
        document, _ = osp_import(osp_dir, mutated(data, osp_system(connections)))
    except SceneError as error:
        assert error.path == str(osp_dir / "OspSystemStructure.xml") and error.problems
    else:
        assert tomllib.loads(tomli_w.dumps(document)) == document


@MUTATIONS
@given(data=st.data())
def test_a_mutated_osp_model_description_is_imported_or_a_scene_error(osp_dir, data):
    (osp_dir / "oscillator_OspModelDescription.xml").write_text(mutated(data, OSP_MODEL_DESCRIPTION))
    try:
        osp_import(osp_dir, osp_system())
    except SceneError as error:
        assert error.path == str(osp_dir / "OspSystemStructure.xml") and error.problems


@MUTATIONS
@given(data=st.data())
def test_a_mutated_ssd_file_is_imported_or_a_scene_error(ssp_dir, data):
    try:
        document, _ = ssd_import(ssp_dir, mutated(data, ssd_system()))
    except SceneError as error:
        assert error.path == str(ssp_dir / "SystemStructure.ssd") and error.problems
    else:
        assert tomllib.loads(tomli_w.dumps(document)) == document


# what an import does not read: a note in check, never silence -------------------------------------------------

OSP_UNIT = ('<InitialValue variable="k"><Real value="10.0"/>',
            '<InitialValue variable="k" unit="degC"><Real value="10.0" unit="degC"/>')
SSV_FOREIGN = ("<ssv:Parameters>", '<ssv:Parameters xmlns:foo="urn:foo"><foo:Extra name="k"/>')


def test_osp_attributes_the_import_does_not_read_are_noted(osp_dir):
    """``unit="degC"`` on an InitialValue (libcosim's schema has none) or on its value is not converted: said."""
    text = osp_system().replace(*OSP_UNIT)
    _, notes = osp_import(osp_dir, text)
    at = f"InitialValue (line {line(text, 'unit=')})"
    assert [n for n in notes if "not read" in n] == [
        f"{at}: InitialValue unit='degC' not read (zencosim reads variable): ignored, the value is used as written",
        f"{at}: Real unit='degC' not read (zencosim reads value): ignored, the value is used as written"]
    _, plain = osp_import(osp_dir, osp_system())
    assert not [n for n in plain if "not read" in n]


def test_ssd_elements_of_parameters_the_import_does_not_read_are_noted(ssp_dir):
    text = ssd_system().replace(*SSV_FOREIGN, 1)
    _, notes = ssd_import(ssp_dir, text)
    assert [n for n in notes if "not read" in n] == [
        f"Extra 'k' (line {line(text, '<foo:Extra')}): an element of Parameters that is no ssv:Parameter is not read "
        "(as fmpy reads a parameter set): ignored"]


def test_check_shows_what_an_import_did_not_read(tmp_path):
    from zencosim.examples.fmus.build import build_fmu

    build_fmu(tmp_path / "oscillator.fmu", 2, ("cs",))
    (tmp_path / "zencosim oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)  # its modelName
    for name, text, said in (("OspSystemStructure.xml", osp_system().replace(*OSP_UNIT), "InitialValue unit='degC'"),
                             ("SystemStructure.ssd", ssd_system().replace(*SSV_FOREIGN, 1), "no ssv:Parameter is")):
        (tmp_path / name).write_text(text)
        with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as errors:
            assert main(["check", str(tmp_path / name)]) == 0, errors.getvalue()
        assert "mapped: " in out.getvalue() and said in " ".join(out.getvalue().split())


step_sizes = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [1e300, 1e308, 5e-324, 1e-9, 1e-10, 9.2e9, 9.3e9, 2.0**63, -1.0, 0.0, 0.001])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(base=step_sizes, step=step_sizes, which=st.sampled_from(["osp base", "osp step", "ssp base"]))
def test_any_float_as_a_step_size_is_imported_or_one_clear_problem(osp_dir, ssp_dir, base, step, which):
    """Every float (NaN, inf, 1e308, subnormal, beyond 64-bit nanoseconds) as a base step or a simulator's step: a
    document whose steps are whole nanoseconds, or a scene error naming the element, never an OverflowError."""
    if which == "ssp base":
        path, text = ssp_dir / "SystemStructure.ssd", ssd_system(base=repr(base))
    else:
        path = osp_dir / "OspSystemStructure.xml"
        text = osp_system(base=repr(base)) if which == "osp base" else osp_system(step_1=repr(step))
    path.write_text(text)
    try:
        document, _ = import_system(path)
    except SceneError as error:
        assert error.path == str(path) and error.problems
        assert all(p.key != "file" and p.reason for p in error.problems)
    else:
        assert 1 <= round(document["manager"]["macro_step"] * 1e9) <= 2**63 - 1
        assert all(1 <= round(s["micro_step"] * 1e9) <= 2**63 - 1 for s in document["subsystems"].values())
