"""Bring your own model: FMUs (built here from the C sources in zencosim/examples/fmus) and a user's
Python class as subsystems, against the built-in models they reproduce.

Tolerances: the FMUs and the example Python model compute the built-in model's equations with the same
method (symplectic Euler, or zencosim's rk4 for Model Exchange), but in a different order of operations
(C and Python scalars against the built-in model's matrix products): each step differs by rounding,
which a damped run of 10 000 steps keeps near 1e-13 relative (measured 3.5e-14 for symplectic Euler,
1.2e-13 for rk4). 1e-12 relative to the signal's largest value is that, with a margin of 10.
"""
from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import zencosim
from tests.conftest import alive, children_of
from zencosim.examples.fmus.build import build_fmu
from zencosim.examples.write import write_examples
from zencosim.manager.bus.zenoh_session import free_tcp_port
from zencosim.subsystems.models.external import model as external_model

ROUNDING = 1e-12  # relative to the signal's largest value (module text)


@pytest.fixture(scope="module")
def examples(tmp_path_factory) -> Path:
    directory = tmp_path_factory.mktemp("examples")
    write_examples(directory)
    build_fmu(directory / "oscillator_nostate.fmu", 2, ("cs",), can_get_and_set_state=False)
    return directory


def _relative_difference(result, reference, signal: str) -> float:
    a, b = result.signal(signal).values, reference.signal(signal).values
    assert a.shape == b.shape
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("scene", ["two_mass_damped_fmu.toml", "two_mass_damped_fmu3.toml",
                                   "two_mass_damped_python.toml"])
def test_fmus_and_a_python_model_reproduce_the_builtin_two_mass_damped(examples, scene):
    result = zencosim.run(examples / scene)
    builtin = zencosim.run("two_mass_damped")
    for signal in ("x2", "fc", "v2"):
        assert _relative_difference(result, builtin, signal) <= ROUNDING, signal
    assert result.summary["energy"]["final"] == pytest.approx(builtin.summary["energy"]["final"], rel=ROUNDING)


@pytest.mark.parametrize("scene", ["two_mass_damped_fmu.toml", "two_mass_damped_fmu3.toml"])
def test_fmus_with_first_order_inputs_reproduce_the_builtin_run(examples, scene):
    """FOH: an input at the step's end differs from the one the step started with, so the outputs (the coupling
    force passes x2 through) are read with the inputs set again; only after a step whose inputs they are read
    with (ZOH, above) does a co-simulation FMU skip that."""
    result = zencosim.run(zencosim.load_scene(str(examples / scene), {"manager.extrapolation": 1}))
    builtin = zencosim.run(zencosim.load_scene("two_mass_damped", {"manager.extrapolation": 1}))
    for signal in ("x2", "fc", "v2"):
        assert _relative_difference(result, builtin, signal) <= ROUNDING, signal


def test_a_model_exchange_fmu_integrated_by_rk4_reproduces_the_builtin_rk4_run(examples):
    result = zencosim.run(examples / "two_mass_damped_fmu_me.toml")
    builtin = zencosim.run(zencosim.load_scene("two_mass_damped", {"subsystems.S1.integrator": "rk4",
                                                                  "subsystems.S2.integrator": "rk4"}))
    for signal in ("x2", "fc"):
        assert _relative_difference(result, builtin, signal) <= ROUNDING, signal


def test_implicit_coupling_rolls_back_fmus_through_their_state(examples):
    result = zencosim.run(examples / "constrained_two_mass_fmu.toml")
    builtin = zencosim.run(zencosim.load_scene("constrained_two_mass", {"subsystems.S1.integrator": "symplectic_euler",
                                                                       "subsystems.S2.integrator": "symplectic_euler"}))
    for signal in ("joint.x1", "joint.f1"):
        assert _relative_difference(result, builtin, signal) <= ROUNDING, signal
    assert result.summary["implicit"]["max_gap"]["position"] < 1e-12  # the joint holds: the rollback worked
    assert result.summary["implicit"]["diverged_at_s"] is None


def test_rollback_is_refused_for_an_fmu_that_cannot_save_its_state(examples):
    text = (examples / "constrained_two_mass_fmu.toml").read_text().replace("oscillator_fmi2.fmu",
                                                                            "oscillator_nostate.fmu")
    (examples / "nostate.toml").write_text(text)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(examples / "nostate.toml")
    message = str(caught.value)
    assert "subsystems.S1.model" in message and "FMU oscillator_nostate.fmu cannot save and restore its state" in message
    assert "canGetAndSetFMUstate" in message


def test_energy_correction_on_an_fmu_bond_corrects_as_on_the_builtin_double_oscillator(examples):
    corrected = {"manager.correction.enabled": True}
    reference = zencosim.run("double_oscillator").summary["energy"]["reference_final"]  # analytic [J]
    fmu = [zencosim.run(zencosim.load_scene(examples / "double_oscillator_fmu.toml", o)) for o in ({}, corrected)]
    builtin = zencosim.run(zencosim.load_scene("double_oscillator", corrected))
    error_plain, error_corrected = (abs(r.summary["energy"]["final"] - reference) / reference for r in fmu)
    assert error_plain > 0.5 and error_corrected < 0.01  # paper 002 Fig. 20: from +103 % to under 1 %
    # undamped: rounding differences are not damped away but grow with the steps (measured 5.4e-11 at 10 s)
    assert fmu[1].summary["energy"]["final"] == pytest.approx(builtin.summary["energy"]["final"], rel=1e-9)
    assert fmu[1].summary["correction"]["work_injected"] < 0


@pytest.mark.multiprocess
@pytest.mark.timeout(300)
@pytest.mark.parametrize("scene", ["two_mass_damped_fmu.toml", "two_mass_damped_fmu3.toml",
                                   "constrained_two_mass_fmu.toml"])
def test_an_fmu_scene_gives_the_same_digest_over_zenoh(examples, scene):
    shortened = zencosim.load_scene(examples / scene, {"manager.duration": 0.5})
    assert zencosim.run(shortened, "zenoh").digest == zencosim.run(shortened).digest


# -- a user's Python model -----------------------------------------------------------------------------------

USER_MODEL = '''
import numpy as np

class Spring:
    """A mass on a spring to ground with an applied force: m a = -k x + f."""
    inputs = {"f": "N"}
    outputs = {"x": "m", "v": "m/s", "E": "J"}
    parameters = {"m": 1.0, "k": 100.0, "x0": 0.1}
    second_order = True

    def __init__(self, m, k, x0):
        self.m, self.k, self.x0 = m, k, x0

    def initial_state(self):
        return np.array([self.x0, 0.0])

    def acceleration(self, t, z, u):
        return np.array([(-self.k * z[0] + u[0]) / self.m])

    def outputs_at(self, t, z, u):
        return np.array([z[0], z[1], 0.5 * self.m * z[1] ** 2 + 0.5 * self.k * z[0] ** 2])
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch) -> Path:
    """A module ``user_spring`` outside the package, importable here and by child processes (PYTHONPATH)."""
    (tmp_path / "user_spring.py").write_text(USER_MODEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    for module in ("user_spring", "broken_spring"):  # each test imports its own copy, not an earlier test's
        monkeypatch.delitem(sys.modules, module, raising=False)
    monkeypatch.setattr(external_model, "_PYTHON_MODELS", {})
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    return tmp_path


def _user_scene(directory: Path, model: str) -> Path:
    """A masses force side (m1, k1, coupling spring to the user's mass) and the user's model as motion side."""
    scene = directory / "user.toml"
    scene.write_text(f'''
name = "user_model"
[manager]
duration = 1.0
macro_step = 0.001
[outputs]
signals = ["x2"]
reference = "none"
[subsystems.S1]
model = "masses"
micro_step = 0.001
bodies.m1 = {{ mass = 1.0, x0 = 0.0 }}
effects.k1 = {{ type = "spring", bodies = ["m1"], stiffness = 10.0 }}
[subsystems.S2]
model = "{model}"
micro_step = 0.001
start = {{ k = 1000.0 }}
energy = "E"
points.p = {{ force_input = "f", position = "x", velocity = "v" }}
[couplings.c]
type = "force_displacement"
force_side = "S1.m1"
motion_side = "S2.p"
force = "fc"
displacement = "x2"
velocity = "v2"
effects.kc = {{ type = "spring", stiffness = 100.0 }}
''')
    return scene


def test_a_python_model_outside_the_package_runs_by_module_and_class(user_module):
    result = zencosim.run(_user_scene(user_module, "user_spring:Spring"))
    # the same system with the built-in masses model as motion side: the same equations, stepped by the same
    # symplectic Euler, so the same trajectory up to rounding
    builtin = (user_module / "user.toml").read_text().replace('model = "user_spring:Spring"', 'model = "masses"')
    builtin = builtin.replace('start = { k = 1000.0 }\nenergy = "E"\npoints.p = { force_input = "f", position = "x", '
                              'velocity = "v" }', 'bodies.p = { mass = 1.0, x0 = 0.1 }\neffects.k2 = { type = "spring", '
                              'bodies = ["p"], stiffness = 1000.0 }')
    (user_module / "builtin.toml").write_text(builtin)
    assert _relative_difference(result, zencosim.run(user_module / "builtin.toml"), "x2") <= ROUNDING


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_python_model_passes_check_model_and_runs_over_zenoh(user_module):
    from tests.manager.test_cli import zencosim as cli
    checked = cli("check-model", "user_spring:Spring", "--start", "k=50")
    assert checked.returncode == 0 and "conforms" in checked.stdout, checked.stderr
    scene = zencosim.load_scene(_user_scene(user_module, "user_spring:Spring"), {"manager.duration": 0.2})
    assert zencosim.run(scene, "zenoh").digest == zencosim.run(scene).digest


BROKEN = {
    "missing method": (USER_MODEL.replace("def outputs_at", "def outputs_now"), "missing method outputs_at()"),
    "non-SI unit": (USER_MODEL.replace('"x": "m"', '"x": "mm"'), "output x: unit 'mm': 'mm' is not an SI unit"),
    "NaN output": (USER_MODEL.replace("return np.array([z[0], z[1]", "return np.array([z[0] * np.nan, z[1]"),
                   "output x is nan at step 1"),
    "undeclared feedthrough": (USER_MODEL.replace("return np.array([z[0], z[1]", "return np.array([z[0] + u[0], z[1]"),
                               "output x changes with the inputs at the same instant but does not declare feedthrough"),
    # an output in J is checked like any other (docs/models.md): only the energy a scene names is zencosim's own
    "undeclared feedthrough in J": (USER_MODEL.replace("0.5 * self.k * z[0] ** 2])",
                                                       "0.5 * self.k * z[0] ** 2 + u[0]])"),
                                    "output E changes with the inputs at the same instant but does not declare "
                                    "feedthrough"),
}


@pytest.mark.multiprocess
@pytest.mark.parametrize("defect", sorted(BROKEN))
def test_check_model_names_what_is_wrong_with_a_broken_model(user_module, defect):
    from tests.manager.test_cli import zencosim as cli
    source, message = BROKEN[defect]
    (user_module / "broken_spring.py").write_text(source)
    result = cli("check-model", "broken_spring:Spring")
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert message in " ".join(result.stdout.split()), result.stdout


def test_a_scene_with_a_broken_model_names_the_subsystem_and_the_defect(user_module):
    (user_module / "broken_spring.py").write_text(BROKEN["non-SI unit"][0])
    with pytest.raises(zencosim.SceneError, match=r"subsystems\.S2\.model: model broken_spring:Spring: output x: "
                                                  r"unit 'mm'"):
        zencosim.load_scene(_user_scene(user_module, "broken_spring:Spring"))
    with pytest.raises(zencosim.SceneError, match=r"subsystems\.S2\.model: model 'nowhere:Spring': cannot import "
                                                  r"module 'nowhere'"):
        zencosim.load_scene(_user_scene(user_module, "nowhere:Spring"))


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_model_in_the_working_directory_is_found_as_python_m_finds_it(tmp_path):
    """``mymodels.msd:Spring`` where ``mymodels/`` is the working directory's, without PYTHONPATH and with the
    working directory kept off the path as the installed ``zencosim`` command keeps it (``-P``): check-model,
    ``check`` and a run over Zenoh (whose subsystem processes search it too) find it; a module that cannot be
    imported, or exits while imported, is bad input (exit 2) in one line."""
    (tmp_path / "mymodels").mkdir()
    (tmp_path / "mymodels" / "__init__.py").write_text("")
    (tmp_path / "mymodels" / "msd.py").write_text(USER_MODEL)
    (tmp_path / "mymodels" / "exits.py").write_text("import sys\nsys.exit(1)\n")
    scene = _user_scene(tmp_path, "mymodels.msd:Spring")
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}

    def cli(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-P", "-m", "zencosim", *args], capture_output=True, text=True,
                              cwd=tmp_path, env=environment, timeout=100)

    checked = cli("check-model", "mymodels.msd:Spring")
    assert checked.returncode == 0 and "conforms" in checked.stdout, checked.stderr
    ran = cli("run", scene.name, "--bus", "zenoh", "--set", "manager.duration=0.05")
    assert ran.returncode == 0, ran.stderr
    for reference, reason in (("mymodels.nowhere:Spring", "cannot import module 'mymodels.nowhere': No module named"),
                              ("mymodels.exits:Spring", "importing 'mymodels.exits' failed: SystemExit: 1")):
        result = cli("check-model", reference)
        assert result.returncode == 2 and len(result.stderr.splitlines()) == 1, result.stderr
        assert result.stderr.startswith(f"error: model '{reference}': {reason}"), result.stderr


# -- bad FMUs ------------------------------------------------------------------------------------------------

def _wrong_version(path: Path) -> None:
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("modelDescription.xml", '<?xml version="1.0"?><fmiModelDescription fmiVersion="1.0" '
                                                 'modelName="old" modelIdentifier="old" guid="{x}" numberOfContinuousStates="0" '
                                                 'numberOfEventIndicators="0"><ModelVariables/></fmiModelDescription>')


BAD_FMUS = {
    "missing file": (["subsystems.S2.fmu='missing.fmu'"], "subsystems.S2.fmu: FMU {dir}/missing.fmu: no such file"),
    "not a zip": (["subsystems.S2.fmu='not_a_zip.fmu'"], "not an FMU (not a zip archive)"),
    "wrong FMI version": (["subsystems.S2.fmu='fmi1.fmu'"], "FMI version 1.0; expected 2.0 or 3.0"),
    "unknown variable": (["subsystems.S2.points.m2.position='xx'"],
                         "subsystems.S2.points.m2.position: the FMI 2.0 Co-Simulation has no real variable 'xx'"),
    "unit mismatch": (["subsystems.S2.points.m2.position='v'"],
                      "subsystems.S2.points.m2.position: v is in [m/s] (m s-1); expected [m] (position)"),
    "unknown start value": (["subsystems.S2.start.mass=2.0"],
                            "subsystems.S2.start.mass: the FMI 2.0 Co-Simulation has no real variable 'mass'"),
}


@pytest.mark.parametrize("defect", sorted(BAD_FMUS))
def test_a_bad_fmu_is_a_scene_error_that_names_it(examples, defect):
    (examples / "not_a_zip.fmu").write_text("this is not a zip archive")
    _wrong_version(examples / "fmi1.fmu")
    overrides, message = BAD_FMUS[defect]
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(examples / "two_mass_damped_fmu.toml", overrides)
    assert message.format(dir=examples) in str(caught.value)


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
@pytest.mark.parametrize("bus", ["inproc", "zenoh"])
def test_an_fmu_whose_dostep_fails_mid_run_is_named_with_its_step_and_status(examples, processes, bus):
    run = processes("run", str(examples / "two_mass_damped_fmu.toml"), "--bus", bus, "--quiet",
                    "--set", "subsystems.S2.start.fail_at=0.25")
    _, stderr = run.communicate(timeout=90)
    assert run.returncode == 1 and "Traceback" not in stderr
    assert ("subsystem S2: failed at step 251: FmuError: FMU oscillator_fmi2.fmu: fmi2DoStep failed with status 3 "
            "(error) while doStep at t = 0.25 s") in " ".join(stderr.split())
    assert not [pid for pid in children_of(run.pid) if alive(pid)]  # no subsystem process left


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_subsystem_started_by_hand_with_another_fmu_file_is_refused(examples, processes, tmp_path):
    """The other host has the same scene text but an FMU built differently: same GUID, other sha256."""
    other = tmp_path / "other_host"
    other.mkdir()
    (other / "two_mass_damped_fmu.toml").write_text((examples / "two_mass_damped_fmu.toml").read_text())
    build_fmu(other / "oscillator_fmi2.fmu", 2, ("cs",), can_serialize_state=False)
    port = free_tcp_port()
    manager = processes("run", str(examples / "two_mass_damped_fmu.toml"), "--bus", "zenoh", "--quiet",
                        "--listen", f"tcp/127.0.0.1:{port}", "--external", "S2")
    helper = processes("subsystem", str(other / "two_mass_damped_fmu.toml"), "S2", "--connect", f"tcp/127.0.0.1:{port}")
    _, stderr = manager.communicate(timeout=90)
    helper.communicate(timeout=30)
    assert manager.returncode == 1
    assert "subsystem S2: its component is not the manager's: sha256" in " ".join(stderr.split())
    assert "give both hosts the same file" in " ".join(stderr.split())


# -- system descriptions users already have -------------------------------------------------------------------

@pytest.mark.multiprocess
@pytest.mark.timeout(120)
@pytest.mark.parametrize("system", ["OspSystemStructure.xml", "SystemStructure.ssd"])
def test_osp_and_ssp_systems_load_as_their_toml_conversion_and_run_the_two_mass_system(examples, tmp_path, system):
    from tests.manager.test_cli import zencosim as cli
    from tests.manager.test_system_imports import OSP_MODEL_DESCRIPTION, osp_system, ssd_system
    directory = tmp_path / "system"
    directory.mkdir()
    (directory / "oscillator.fmu").write_bytes((examples / "oscillator_fmi2.fmu").read_bytes())
    (directory / "zencosim oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)
    (directory / system).write_text(osp_system() if system.endswith(".xml") else ssd_system())
    converted = cli("convert", str(directory / system), "--to", str(directory / "converted.toml"))
    assert converted.returncode == 0, converted.stderr
    imported = zencosim.load_scene(directory / system)
    assert imported.digest == zencosim.load_scene(directory / "converted.toml").digest  # the same scene
    assert imported.notes and "mapped:" in cli("check", str(directory / system)).stdout
    run = zencosim.run(imported)
    builtin = zencosim.run("two_mass_damped")
    x2 = run.signal("c1.x").values
    assert np.max(np.abs(x2 - builtin.signal("x2").values)) <= ROUNDING * np.max(np.abs(builtin.signal("x2").values))


def test_a_model_a_package_registers_in_the_entry_points_is_found_by_name(user_module):
    """What pip writes for a package that declares [project.entry-points."zencosim.models"]."""
    info = user_module / "user_models-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: user-models\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[zencosim.models]\nspring = user_spring:Spring\n")
    by_name = zencosim.run(zencosim.load_scene(_user_scene(user_module, "spring"), {"manager.duration": 0.1}))
    by_class = zencosim.run(zencosim.load_scene(_user_scene(user_module, "user_spring:Spring"), {"manager.duration": 0.1}))
    assert by_name.digest == by_class.digest
    with pytest.raises(zencosim.SceneError, match="no model 'sprung': expected a built-in model, 'fmu', "
                                                  "'package.module:Class' or a name registered in the entry-point "
                                                  "group 'zencosim.models' \\(spring\\)"):
        zencosim.load_scene(_user_scene(user_module, "sprung"))


@pytest.mark.multiprocess
def test_zencosim_examples_writes_scenes_that_load(tmp_path):
    from tests.manager.test_cli import zencosim as cli
    result = cli("examples", str(tmp_path / "examples"))
    assert result.returncode == 0, result.stderr
    written = sorted(p.name for p in (tmp_path / "examples").glob("*.toml"))
    assert "two_mass_damped_fmu.toml" in written and "two_mass_damped_python.toml" in written
    for scene in written:
        zencosim.load_scene(tmp_path / "examples" / scene)
