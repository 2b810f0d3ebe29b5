"""FMUs exported by third-party tools, run as their authors meant them and checked against the tools they were
made for (issue 24, item 6).

* pythonfmu: a PI controller written here as an ``Fmi2Slave`` and exported with pythonfmu's builder drives the
  example oscillator FMU through two signal connections; zencosim (TOML scene) against libcosim (the same two
  FMUs in an OSP file with plain ``VariableConnection``s), and zencosim in process against zencosim over Zenoh.
* crane-fmu 0.2.0: its authors' two fixed-step systems, one FMU each (``HarmonicOscillator6D.fmu``,
  ``MobileCrane.fmu``, made with component-model and pythonfmu), run alone by zencosim and by
  ``fmpy.simulate_fmu`` with their default experiment and the same input table, each in a process of its own
  (``tests/interop/lone_fmu_process.py`` says why).

Measured and explained in docs/interop.md ("FMUs from other tools").
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu", reason="pythonfmu exports the controller FMU (pip install pythonfmu)")

import zencosim  # noqa: E402
from tests.interop.measures import AGREEMENT, largest_difference  # noqa: E402
from tests.interop.pythonfmu_pair import (  # noqa: E402
    CONTROLLER_START,
    DURATION,
    PLANT_START,
    STEP,
    build_controller,
    write_osp,
    write_scene,
)

ROOT = Path(__file__).resolve().parents[2]
STEPS = round(DURATION / STEP)


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> dict[str, Path]:
    """The controller FMU (exported here), the plant FMU and the system as a TOML scene and an OSP file."""
    if shutil.which("gcc") is None:
        pytest.skip("building the example oscillator FMU needs gcc")
    from zencosim.examples.write import write_examples

    root = tmp_path_factory.mktemp("pythonfmu_pair")
    write_examples(root / "examples")
    plant = root / "examples" / "oscillator_fmi2.fmu"
    controller = build_controller(root / "build")
    system = root / "system"
    system.mkdir()
    return {"controller": controller, "scene": write_scene(system, plant, controller),
            "osp": write_osp(system, plant, controller)}


@pytest.fixture(scope="module")
def zencosim_run(pair):
    return zencosim.run(zencosim.load_scene(str(pair["scene"])))


@pytest.mark.multiprocess
def test_the_pythonfmu_controller_is_an_fmi2_cosimulation_fmu_fmpy_runs(pair):
    """fmpy.simulate_fmu runs it alone, position held at 0: the error is the setpoint. In a process of its own:
    after fmpy.simulate_fmu has run a pythonfmu FMU, a process that opens a Zenoh session (the next test) aborts
    at exit with "corrupted double-linked list" (measured; docs/interop.md)."""
    import fmpy

    description = fmpy.read_model_description(str(pair["controller"]))
    assert description.fmiVersion == "2.0" and description.generationTool.startswith("PythonFMU")
    assert {v.name: v.causality for v in description.modelVariables} == {
        "kp": "parameter", "ki": "parameter", "setpoint": "parameter", "position": "input", "force": "output"}
    code = ("import json, sys, fmpy\n"
            f"r = fmpy.simulate_fmu({str(pair['controller'])!r}, start_values={CONTROLLER_START!r}, "
            f"stop_time=0.05, output_interval={STEP!r})\n"
            "json.dump([r['time'].tolist(), r['force'].tolist()], sys.stdout)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    time, force = (np.array(column) for column in json.loads(run.stdout))
    kp, ki, r = CONTROLLER_START["kp"], CONTROLLER_START["ki"], CONTROLLER_START["setpoint"]
    assert len(time) == 6
    np.testing.assert_allclose(force, kp * r + ki * r * time, rtol=1e-12, atol=0)


def test_zencosim_gives_libcosims_answer_on_the_controlled_plant(pair, zencosim_run):
    """x, v and the force agree with libcosim to rounding (the step handed to doStep: libcosim's t_{k+1} - t_k
    of rounded time points, zencosim's exact step). a feeds f_in through; zencosim and libcosim read it with the
    same f_in (the force of the step before, held) at every step but the first: at t = 0 libcosim samples the
    plant before handing it the force the controller computes when it leaves initialisation (20 N), zencosim
    after, so a(0) = 0 there and f(0)/m = 10 m/s2 here, and the first step uses 20 N in both."""
    pytest.importorskip("libcosimpy")
    from tests.interop.libcosim_oracle import run_osp

    theirs = run_osp(pair["osp"], DURATION, [("plant", "x"), ("plant", "v"), ("plant", "a"), ("controller", "force")])
    assert np.array_equal(theirs.steps, np.arange(STEPS + 1))
    assert np.allclose(zencosim_run.signal("x").time, theirs.time, rtol=0, atol=1e-12)
    for name, key in (("x", ("plant", "x")), ("v", ("plant", "v")), ("force", ("controller", "force"))):
        assert largest_difference(zencosim_run.signal(name).values, theirs[key]) <= AGREEMENT, name
    ours_a, theirs_a = zencosim_run.signal("a").values, theirs[("plant", "a")]
    assert largest_difference(ours_a[1:], theirs_a[1:]) <= AGREEMENT
    force0 = CONTROLLER_START["kp"] * CONTROLLER_START["setpoint"]
    assert (ours_a[0], theirs_a[0]) == (force0 / PLANT_START["m"], 0.0)
    # it is controlled: the position rises from 0 past the setpoint, and the force changes sign
    x = zencosim_run.signal("x").values
    assert x[0] == 0.0 and x.max() > CONTROLLER_START["setpoint"] and zencosim_run.signal("force").values.min() < 0
    # the signal connections copy values unchanged: the force reaches f_in as it left the controller
    assert np.array_equal(zencosim_run.signal("actuation").values, zencosim_run.signal("force").values)


@pytest.mark.multiprocess
@pytest.mark.cpu_timeout(120)  # about 5 s of CPU with the pair's build; on a loaded machine 300 s of wall were too few
def test_the_controlled_plant_gives_one_digest_on_both_buses(pair, zencosim_run):
    assert zencosim.run(zencosim.load_scene(str(pair["scene"])), bus="zenoh").digest == zencosim_run.digest


# ---- crane-fmu: its authors' FMUs, each alone, against fmpy.simulate_fmu --------------------------------------

# Input tables: the FMUs' outputs stay at their start values without inputs. Columns are input variables
# (fmpy's read_csv splits on every comma, so no der(x,2) columns); times on the 0.01 s grid.
CRANE_CASES = {
    # 6 uncoupled damped oscillators (scipy's solve_ivp per step), 10 s: a force ramp, hold and jump on axes 2, 3
    "HarmonicOscillator6D": "time,f[2],f[3]\n0.0,0.0,0.0\n1.0,2.0,0.5\n3.0,2.0,0.5\n3.0,-1.0,0.0\n6.0,0.0,0.0\n",
    # a mobile crane, 1 s: luffing and extending the boom and slewing for 0.4 s
    "MobileCrane": ("time,der(boom.boom[1]),der(boom.boom[0]),d_angular[2]\n0.0,0.0,0.0,0.0\n0.2,-0.1,0.5,0.05\n"
                    "0.6,-0.1,0.5,0.05\n0.6,0.0,0.0,0.0\n1.0,0.0,0.0,0.0\n"),
}
# measured: MobileCrane 4.9e-16, HarmonicOscillator6D 1.2e-13 (of each output's largest magnitude); the
# replicas show the whole difference is the doStep arguments (fmpy: t_n = n h, h_n = t_{n+1} - t_n; zencosim:
# exact h), which solve_ivp's adaptive steps carry to 1e-13
CRANE_TOLERANCE = 1e-12


def crane_fmu(name: str) -> Path:
    """An FMU crane-fmu's wheel installs (``examples/<name>.fmu`` in site-packages)."""
    try:
        distribution = metadata.distribution("crane-fmu")
    except metadata.PackageNotFoundError:
        pytest.skip("crane-fmu is not installed (pip install 'crane-fmu>=0.2'): its FMUs come with it")
    path = Path(distribution.locate_file(f"examples/{name}.fmu"))
    if not path.is_file():
        pytest.skip(f"crane-fmu {distribution.version} ships no examples/{name}.fmu")
    return path


def run_alone(tool: str, fmu: Path, table: Path, out: Path) -> dict[str, np.ndarray]:
    """What ``tool`` gives running ``fmu`` alone, in a process of its own (no wall-clock limit: the test's
    ``cpu_timeout`` counts this process's CPU and ends it when it hangs)."""
    run = subprocess.run([sys.executable, "-m", "tests.interop.lone_fmu_process", tool, str(fmu), str(table),
                          str(out)], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, f"{tool} on {fmu.name}: {run.stderr[-2000:]}"
    with np.load(out) as data:
        return dict(data)


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.cpu_timeout(120)  # HarmonicOscillator6D: 9 s of CPU for its four runs (31 s of wall at a load of 6)
@pytest.mark.parametrize("name", sorted(CRANE_CASES))
def test_a_crane_fmu_alone_gives_what_fmpy_simulate_fmu_gives(name, tmp_path):
    fmu = crane_fmu(name)
    table = tmp_path / "inputs.csv"
    table.write_text(CRANE_CASES[name])
    runs = {tool: run_alone(tool, fmu, table, tmp_path / f"{tool}.npz")
            for tool in ("fmpy", "zencosim", "replica-fmpy", "replica-zencosim")}
    theirs, ours = runs["fmpy"], runs["zencosim"]
    outputs = [key for key in theirs if key != "time"]
    assert sorted(outputs) == sorted(key for key in ours if key != "time")
    assert np.allclose(ours["time"], theirs["time"], rtol=0, atol=1e-12)
    moved = 0
    for output in outputs:
        if np.ptp(theirs[output]) > 0:
            moved += 1
            assert largest_difference(ours[output], theirs[output]) <= CRANE_TOLERANCE, output
        else:
            assert np.array_equal(ours[output], theirs[output]), output
        # the loop written out with each tool's doStep arguments is that tool, bit for bit
        assert np.array_equal(runs["replica-fmpy"][output], theirs[output]), output
        assert np.array_equal(runs["replica-zencosim"][output], ours[output]), output
    assert moved >= 4  # the inputs move it


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_crane_fmu_fails_to_instantiate_without_its_python_dependencies(tmp_path):
    """The cause of "Failed to instantiate model": the model class runs in the host's interpreter, and its
    bundled component_model imports pint (the FMU's requirements.txt: numpy, pint; it needs scipy too), which
    must be installed there. fmpy's debug log shows the Python error the FMU hit."""
    fmu = crane_fmu("MobileCrane")
    hidden = tmp_path / "hide"
    hidden.mkdir()
    (hidden / "pint.py").write_text("raise ImportError('pint is not installed')\n")
    code = (f"import fmpy\nfmpy.simulate_fmu({str(fmu)!r}, stop_time=0.02, debug_logging=True)\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": str(hidden), "PATH": "/usr/bin:/bin"})
    assert run.returncode != 0
    assert "Failed to instantiate model" in run.stderr
    assert "ImportError('pint is not installed')" in run.stdout + run.stderr


@pytest.mark.multiprocess
def test_zencosim_names_an_fmu_that_cannot_be_instantiated_in_one_line(tmp_path):
    """The same FMU without pint, run by zencosim: one line naming the subsystem, the FMU and fmpy's error, and
    exit 2 (the FMU cannot be used here), not a traceback."""
    fmu = crane_fmu("MobileCrane")
    hidden = tmp_path / "hide"
    hidden.mkdir()
    (hidden / "pint.py").write_text("raise ImportError('pint is not installed')\n")
    run = subprocess.run([sys.executable, "-m", "zencosim", "run", str(fmu)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(hidden)})
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    assert "subsystems.MobileCrane.fmu: FMU MobileCrane.fmu: cannot be instantiated (Exception: Failed to " \
           "instantiate model)" in run.stderr
