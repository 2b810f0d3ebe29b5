"""Units of FMU variables: a variable that declares none (check-model names it; a scene's ``units`` table
gives it), and unit definitions with a factor and offset, converted at the FMU's boundary.

The FMUs are the example oscillator compiled here (zencosim/examples/fmus) with a rewritten
modelDescription: the same binary, whose arithmetic does not know units, declared in other units. An
FMU in millimetres is then a consistent model of the same system when every quantity that involves a
length is declared accordingly (x in mm, k in N/mm, m in t so that N/t = mm/s², E in mJ, …): in SI it
must follow the metre FMU's trajectory. The two differ by rounding only: the converted start values
and exchanged values are each within an ulp or so of the exact ones, and the arithmetic on numbers 1000
times larger rounds differently; the runs are damped, so these differences do not grow much (measured
relative to the signal's largest value: at most 2.8e-15 over the 2 s runs here, 7.2e-15 over 10 s, both
interfaces; 1.0e-15 for the datum test's outputs). 1e-13 is that with a margin of 30; a lost factor or
offset is wrong by orders of magnitude more (x × 1000, or x off by 0.25 m).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest

import zencosim
from zencosim.examples.write import write_examples
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models import model_traits
from zencosim.subsystems.models.conformance import _drive, check_component
from zencosim.subsystems.models.external.fmu import describe_fmu
from zencosim.subsystems.models.external.model import ExternalSpec, FmuModel
from zencosim.subsystems.params import Problems
from zencosim.subsystems.subsystem import Subsystem

ROUNDING = 1e-13  # relative to the signal's largest value (module text)

# name -> (base-unit exponents, factor, offset), FMI's BaseUnit: value_SI = factor * value + offset
MM_UNITS = {
    "mm": ({"m": 1}, 1e-3, 0.0),
    "mm/s": ({"m": 1, "s": -1}, 1e-3, 0.0),
    "mm/s2": ({"m": 1, "s": -2}, 1e-3, 0.0),
    "t": ({"kg": 1}, 1e3, 0.0),
    "1/t": ({"kg": -1}, 1e-3, 0.0),
    "N/mm": ({"kg": 1, "s": -2}, 1e3, 0.0),
    "N.s/mm": ({"kg": 1, "s": -1}, 1e3, 0.0),
    "mJ": ({"kg": 1, "m": 2, "s": -2}, 1e-3, 0.0),
}
IN_MM = {"x": "mm", "x_in": "mm", "x0": "mm", "v": "mm/s", "v_in": "mm/s", "v0": "mm/s", "a": "mm/s2", "m": "t",
         "inverse_mass": "1/t", "k": "N/mm", "kc": "N/mm", "c": "N.s/mm", "cc": "N.s/mm", "E": "mJ"}
DATUM = 0.25  # [m] where the position unit "mm from the datum" has its zero
WITH_DATUM = {**MM_UNITS, "mm from datum": ({"m": 1}, 1e-3, DATUM)}


def rewrite_units(source: Path, target: Path, variables: dict[str, str | None],
                  definitions: dict[str, tuple[dict[str, int], float, float]] | None = None,
                  relative: tuple[str, ...] = ()) -> Path:
    """A copy of the FMI 2.0 FMU ``source`` whose variables are declared in other units (None: no unit), with
    more unit definitions; ``relative``: variables marked relativeQuantity."""
    with zipfile.ZipFile(source) as archive:
        files = {name: archive.read(name) for name in archive.namelist()}
    root = ET.fromstring(files["modelDescription.xml"])
    units = root.find("UnitDefinitions")
    for name, (exponents, factor, offset) in (definitions or {}).items():
        ET.SubElement(ET.SubElement(units, "Unit", name=name), "BaseUnit",
                      {**{k: str(e) for k, e in exponents.items()}, "factor": repr(factor), "offset": repr(offset)})
    for variable in root.iter("ScalarVariable"):
        real = variable.find("Real")
        name = variable.get("name")
        if name in variables:
            if variables[name] is None:
                real.attrib.pop("unit", None)
            else:
                real.set("unit", variables[name])
        if name in relative:
            real.set("relativeQuantity", "true")
    files["modelDescription.xml"] = ET.tostring(root, encoding="unicode").encode()
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return target


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    """The examples, and the oscillator FMU without a unit for fc, in millimetres, and in mm from a datum."""
    directory = tmp_path_factory.mktemp("fmu_units")
    write_examples(directory)
    metre = directory / "oscillator_fmi2.fmu"
    rewrite_units(metre, directory / "no_unit.fmu", {"fc": None})
    rewrite_units(metre, directory / "mm.fmu", IN_MM, MM_UNITS)
    datum = {**IN_MM, "x": "mm from datum", "x_in": "mm from datum", "x0": "mm from datum"}
    rewrite_units(metre, directory / "datum.fmu", datum, WITH_DATUM)
    return directory


def _scene(fmus: Path, name: str, fmu: str, extra: str = "", source: str = "two_mass_damped_fmu.toml") -> Path:
    """An example scene with both subsystems' FMU replaced (``extra``: lines added to both subsystem tables)."""
    text = (fmus / source).read_text()
    original = "oscillator_fmi2.fmu"
    text = text.replace(f'fmu = "{original}"', f'fmu = "{fmu}"\n{extra}')
    path = fmus / name
    path.write_text(text)
    return path


# -- a variable without a unit ------------------------------------------------------------------------------

def test_check_model_names_a_variable_without_unit_and_checks_the_rest(fmus):
    problems = check_component(str(fmus / "no_unit.fmu"), {"kc": 100.0})
    assert len(problems) == 1 and problems[0].startswith("output fc: declares no unit"), problems
    assert "--unit fc=UNIT" in problems[0]
    assert check_component(str(fmus / "no_unit.fmu"), {"kc": 100.0}, units={"fc": "N"}) == []
    assert "not the same quantity" in check_component(str(fmus / "no_unit.fmu"), {}, units={"x": "N"})[0]


@pytest.mark.multiprocess
def test_check_model_on_an_fmu_without_units_exits_1_naming_it_and_2_for_no_fmu(fmus):
    from tests.manager.test_cli import zencosim as cli
    checked = cli("check-model", str(fmus / "no_unit.fmu"))
    assert checked.returncode == 1 and "Traceback" not in checked.stderr, checked.stderr
    assert "FAILED: output fc: declares no unit" in checked.stdout and "building it failed" not in checked.stdout
    assert cli("check-model", str(fmus / "no_unit.fmu"), "--unit", "fc=N").returncode == 0
    missing = cli("check-model", str(fmus / "missing.fmu"))
    assert missing.returncode == 2 and "no such file" in missing.stderr and "Traceback" not in missing.stderr


def test_a_scene_refuses_an_fmu_variable_without_unit_and_runs_with_the_scenes_units(fmus):
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(_scene(fmus, "no_unit.toml", "no_unit.fmu"))
    assert ('subsystems.S1.points.m1.force: fc: declares no unit; expected [N] (force): declare it in the '
            "subsystem's units table, units = { fc = \"N\" }") in " ".join(str(caught.value).split())
    duration = {"manager.duration": 1.0}
    given = zencosim.run(zencosim.load_scene(_scene(fmus, "units.toml", "no_unit.fmu", 'units = { fc = "N" }'),
                                             duration))
    reference = zencosim.run(zencosim.load_scene(fmus / "two_mass_damped_fmu.toml", duration))
    for signal in ("x2", "fc", "v2"):  # the same binary, no conversion: the same numbers
        assert np.array_equal(given.signal(signal).values, reference.signal(signal).values), signal


@pytest.mark.parametrize("units,message", [
    ('{ x = "N" }', "subsystems.S1.units.x: x: the FMI 2.0 Co-Simulation declares [m] (m), the scene [N] "
                    "(kg m s-2): not the same quantity"),
    ('{ y = "m" }', "subsystems.S1.units.y: the FMI 2.0 Co-Simulation has no real variable 'y'"),
    ('{ fc = "kN" }', "subsystems.S1.units.fc: 'kN': 'kN' is not an SI unit"),
    ('{ fc = 1.0 }', "subsystems.S1.units.fc: expected an SI unit as a string"),
])
def test_scene_units_that_contradict_the_fmu_or_are_not_si_are_refused(fmus, units, message):
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(_scene(fmus, "bad_units.toml", "no_unit.fmu", f"units = {units}"))
    assert message in " ".join(str(caught.value).split())


# -- units with a factor and offset ---------------------------------------------------------------------------

def test_unit_definitions_give_factor_and_offset_and_a_relative_quantity_ignores_the_offset(fmus):
    celsius = {"degC": ({"K": 1}, 1.0, 273.15), "bar": ({"kg": 1, "m": -1, "s": -2}, 1e5, 0.0)}
    path = rewrite_units(fmus / "oscillator_fmi2.fmu", fmus / "celsius.fmu", {"x": "degC", "v": "degC", "a": "bar"},
                         celsius, relative=("v",))
    variables = describe_fmu(path, None).variables
    assert (variables["x"].factor, variables["x"].offset, variables["x"].exponents[4]) == (1.0, 273.15, 1)
    assert (variables["v"].factor, variables["v"].offset) == (1.0, 0.0)  # a temperature difference
    assert (variables["a"].factor, variables["a"].offset) == (1e5, 0.0)
    assert variables["x"].to_component(300.0) == pytest.approx(26.85)


def _relative_difference(result, reference, signal: str) -> float:
    a, b = result.signal(signal).values, reference.signal(signal).values
    assert a.shape == b.shape
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("source", ["two_mass_damped_fmu.toml", "two_mass_damped_fmu_me.toml"])
def test_an_fmu_in_millimetres_follows_the_metre_fmus_si_trajectory(fmus, source):
    """Co-Simulation (symplectic Euler inside) and Model Exchange (zencosim's rk4 on the FMU's state in mm)."""
    duration = {"manager.duration": 2.0}
    reference = zencosim.run(zencosim.load_scene(fmus / source, duration))
    result = zencosim.run(zencosim.load_scene(_scene(fmus, "mm.toml", "mm.fmu", source=source), duration))
    for signal in ("x2", "fc", "v2"):
        assert _relative_difference(result, reference, signal) <= ROUNDING, signal
    assert np.max(np.abs(reference.signal("x2").values)) > 1.0  # metres, not millimetres
    energy, expected = result.summary["energy"]["final"], reference.summary["energy"]["final"]
    assert energy == pytest.approx(expected, rel=ROUNDING)  # the outputs E in mJ, converted to J


def _subsystem(path: Path, start: dict[str, float]) -> Subsystem:
    description = describe_fmu(path, None)
    spec = ExternalSpec("fmu", description, path, start, None, {})
    integrator = INTEGRATORS[model_traits(FmuModel, spec).default_integrator]  # co-simulation: its own
    return Subsystem(path.name, FmuModel(spec, expose_all=True), integrator, 1_000_000)


def test_an_offset_and_a_factor_convert_inputs_outputs_and_start_values_both_ways(fmus):
    """Every variable exposed (as check-model does) and driven by the same random input polynomials: the FMU
    whose positions are millimetres from a datum 0.25 m away gives the metre FMU's SI outputs. Without a
    spring to ground (k = 0) the model depends on positions only through x - x_in, so the datum is no
    other system; a lost offset would shift x by 0.25 m, a lost factor scale it by 1000."""
    start = {"m": 2.0, "kc": 100.0, "cc": 0.5, "c": 0.1, "x0": 0.4, "v0": -1.0}
    metre, datum = (_subsystem(fmus / name, start) for name in ("oscillator_fmi2.fmu", "datum.fmu"))
    assert [p.name for p in datum.inputs] == ["x_in", "v_in", "f_in"]
    a, b = (_drive(s, np.random.default_rng(3), 0, 200, 1_000_000, 3) for s in (metre, datum))
    scale = np.max(np.abs(a), axis=0)
    assert np.all(np.abs(b - a) <= ROUNDING * scale), np.max(np.abs(b - a) / scale, axis=0)
    assert a[0, 0] != pytest.approx(a[-1, 0], abs=1e-3)  # the position moved


# -- system imports --------------------------------------------------------------------------------------------

def test_an_osp_system_whose_fmu_declares_no_units_imports_with_the_units_its_groups_give(fmus, tmp_path):
    """The OSP model description states the units of its port groups' variables (fc in N, v in m/s, …): the
    imported scene says them in units tables, loads and runs as the system with the FMU that declares them."""
    from tests.manager.test_system_imports import OSP_MODEL_DESCRIPTION, osp_system
    from zencosim.manager.scene.imports import import_system
    unitless = ("fc", "f_in", "v", "v_in")
    runs = []
    for name, variables in (("declared", {}), ("unitless", dict.fromkeys(unitless))):
        directory = tmp_path / name
        directory.mkdir()
        rewrite_units(fmus / "oscillator_fmi2.fmu", directory / "oscillator.fmu", variables)
        (directory / "zencosim oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)
        (directory / "OspSystemStructure.xml").write_text(osp_system())
        document, notes = import_system(directory / "OspSystemStructure.xml", 1.0)
        if name == "unitless":
            assert document["subsystems"]["S1"]["units"] == {"fc": "N", "v_in": "m/s"}
            assert document["subsystems"]["S2"]["units"] == {"f_in": "N", "v": "m/s"}
            assert any(note.startswith("subsystems.S1.units = ") for note in notes)
        else:
            assert all("units" not in table for table in document["subsystems"].values())
        runs.append(zencosim.run(zencosim.load_scene(directory / "OspSystemStructure.xml", {"manager.duration": 1.0})))
    assert np.array_equal(runs[0].signal("c1.x").values, runs[1].signal("c1.x").values)


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_scene_with_converted_units_gives_the_same_digest_over_zenoh(fmus):
    """Each subsystem process reads the units (the scene's and the FMU's) and converts as the manager does."""
    rewrite_units(fmus / "mm.fmu", fmus / "mm_no_fc.fmu", {"fc": None})
    scene = zencosim.load_scene(_scene(fmus, "mm_zenoh.toml", "mm_no_fc.fmu", 'units = { fc = "N" }'),
                                {"manager.duration": 0.2})
    assert zencosim.run(scene, "zenoh").digest == zencosim.run(scene).digest


# -- a declared dimensionless unit, replaced by the scene's ------------------------------------------------------

COUPLED = {"fc": "N", "x_in": "m", "v_in": "m/s", "f_in": "N", "x": "m", "v": "m/s"}


def test_scene_units_replace_a_dimensionless_unit_and_the_bond_runs_as_with_si_units(fmus):
    """pint-style FMUs declare "dimensionless": refused as a bond's variables, until the scene's units replace it;
    then the same binary gives the SI FMU's run bit for bit, residual energy included, and the summary says it."""
    rewrite_units(fmus / "oscillator_fmi2.fmu", fmus / "pint.fmu", dict.fromkeys(COUPLED, "dimensionless"),
                  {"dimensionless": ({}, 1.0, 0.0)})
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(_scene(fmus, "pint_bare.toml", "pint.fmu"))
    assert "subsystems.S1.points.m1.force: fc is in [dimensionless] (1); expected [N] (force)" in str(caught.value)
    units = ", ".join(f'{name} = "{unit}"' for name, unit in COUPLED.items())
    duration = {"manager.duration": 1.0}
    given = zencosim.run(zencosim.load_scene(_scene(fmus, "pint.toml", "pint.fmu", f"units = {{ {units} }}"),
                                             duration))
    reference = zencosim.run(zencosim.load_scene(fmus / "two_mass_damped_fmu.toml", duration))
    assert given.summary["digest"] == reference.summary["digest"]
    assert given.summary["residual_energy"] == reference.summary["residual_energy"] != {"c": 0.0}
    assert given.summary["replaced_units"]["S2.f_in"] == {"declared": "dimensionless", "scene": "N"}
    assert len(given.summary["replaced_units"]) == 2 * len(COUPLED) and "replaced_units" not in reference.summary


def test_a_scene_unit_that_contradicts_a_real_declared_unit_is_refused(fmus):
    """x declares m: a real unit stays the FMU's; rad/s for a unit lacking only the radian (pint's s-1) is taken."""
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(_scene(fmus, "contradicts.toml", "oscillator_fmi2.fmu", 'units = { x = "rad" }'))
    assert ("subsystems.S1.units.x: x: the FMI 2.0 Co-Simulation declares [m] (m), the scene [rad] (rad): not the "
            "same quantity (a scene's unit replaces a declared one only where that is dimensionless, or lacks only "
            "the radian)") in " ".join(str(caught.value).split())
    path = rewrite_units(fmus / "oscillator_fmi2.fmu", fmus / "per_s.fmu", {"v": "radian / second"},
                         {"radian / second": ({"s": -1, "rad": 0}, 1.0, 0.0)})
    problems = Problems()
    spec = FmuModel.read({"fmu": path.name, "units": {"v": "rad/s"}}, "S", problems, fmus)
    assert not problems and spec.replaced_units == {"v": ("radian / second", "rad/s")}
