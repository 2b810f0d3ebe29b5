"""One FMU run alone (``zencosim run model.fmu``), against ``fmpy.simulate_fmu`` on the same FMU with the same step:
the oracle is the tool the FMU was made for, not zencosim's own arithmetic. Also inputs from a table and start
values, and what is refused."""
from __future__ import annotations

import contextlib
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zencosim
from zencosim.cli.main import main
from zencosim.examples.write import write_examples

fmpy = pytest.importorskip("fmpy")

START = {"m": 1.5, "k": 12.0, "c": 0.3, "kc": 4.0, "cc": 0.05, "x0": 0.2, "v0": -1.0}
OUTPUTS = ("x", "v", "a", "fc", "E")
# zencosim passes each doStep the step h itself and fmpy (start + (n+1) h) - t, which can differ in the last bit;
# the oscillator's symplectic Euler does not use t, so the trajectories agree to round-off of the step only
TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    directory = tmp_path_factory.mktemp("lone")
    write_examples(directory)
    return directory / "oscillator_fmi2.fmu"


def inputs_csv(path: Path) -> Path:
    """f_in [N]: a ramp, a step at 0.3 s (a time given twice) and a hold after the last sample."""
    path.write_text("time,f_in\n0.0,0.0\n0.25,2.0\n0.3,2.0\n0.3,-1.0\n0.7,0.5\n")
    return path


def table_columns(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = fmpy.util.read_csv(path)
    return data["time"], data["f_in"][np.newaxis, :]


def fmpy_result(fmu: Path, step: float, stop: float, input_table: Path | None = None) -> np.ndarray:
    signals = None if input_table is None else fmpy.util.read_csv(input_table)
    return fmpy.simulate_fmu(str(fmu), start_values=START, stop_time=stop, output_interval=step, input=signals,
                             output=list(OUTPUTS))


def zencosim_result(fmu: Path, step: float, stop: float, input_table: Path | None = None, bus: str = "inproc"):
    overrides = {f"start.{name}": value for name, value in START.items()}
    overrides |= {"manager.macro_step": step, "manager.duration": stop, f"subsystems.{NAME}.micro_step": step}
    if input_table is not None:
        overrides["input"] = str(input_table)
    return zencosim.run(zencosim.load_scene(str(fmu), overrides), bus=bus)


NAME = "zencosim_oscillator"  # the subsystem: the FMU's model identifier


def largest_difference(result, reference: np.ndarray, names: tuple[str, ...] = OUTPUTS) -> float:
    worst = 0.0
    for name in names:
        signal = result.signal(name)
        assert np.allclose(signal.time, reference["time"], rtol=0, atol=1e-12)
        scale = max(np.abs(reference[name]).max(), 1e-300)
        worst = max(worst, float(np.abs(signal.values - reference[name]).max() / scale))
    return worst


@pytest.mark.parametrize("step", [0.001, 0.004])
def test_a_lone_fmu_gives_what_fmpy_simulate_fmu_gives(fmu, step):
    result = zencosim_result(fmu, step, 1.0)
    assert largest_difference(result, fmpy_result(fmu, step, 1.0)) <= TOLERANCE
    assert result.signal("x").values[0] == START["x0"] and np.ptp(result.signal("x").values) > 0.1  # it moved


def test_inputs_from_a_table_are_set_as_fmpy_sets_them(fmu, tmp_path):
    table = inputs_csv(tmp_path / "inputs.csv")
    result = zencosim_result(fmu, 0.01, 1.0, table)
    reference = fmpy_result(fmu, 0.01, 1.0, table)
    assert largest_difference(result, reference, ("x", "v", "fc", "E")) <= TOLERANCE
    # the table matters: without it the run differs by far more than the tolerance
    assert largest_difference(zencosim_result(fmu, 0.01, 1.0), reference, ("x", "v")) > 1e-3
    # a = (... + f_in)/m feeds f_in through: zencosim reads it after setting the inputs of the step's end
    # (docs/numerics.md), fmpy before, so the two differ by exactly the input's change over the step, over m
    f_in = np.array([fmpy.simulation.Input.interpolate(t, *table_columns(table), after_event=True)[0][0]
                     for t in reference["time"]])
    previous = np.concatenate(([f_in[0]], f_in[:-1]))
    np.testing.assert_allclose(result.signal("a").values - reference["a"], (f_in - previous) / START["m"],
                               rtol=0, atol=1e-12)
    assert np.abs(f_in - previous).max() == 3.0  # the step at 0.3 s is in it


@pytest.mark.multiprocess
def test_a_lone_fmu_gives_one_digest_on_both_buses(fmu, tmp_path):
    table = inputs_csv(tmp_path / "inputs.csv")
    assert zencosim_result(fmu, 0.01, 0.5, table).digest == zencosim_result(fmu, 0.01, 0.5, table, "zenoh").digest


def test_the_command_line_runs_a_lone_fmu_with_inputs_and_writes_its_outputs(fmu, tmp_path):
    table = inputs_csv(tmp_path / "inputs.csv")
    out = tmp_path / "out.csv"
    sets = [part for name, value in START.items() for part in ("--set", f"start.{name}={value}")]
    run = subprocess.run([sys.executable, "-m", "zencosim", "run", str(fmu), "--input", str(table), "--out", str(out),
                          "--set", "manager.macro_step=0.01", "--set", "manager.duration=1.0",
                          "--set", f"subsystems.{NAME}.micro_step=0.01", *sets],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    written = np.genfromtxt(out, delimiter=",", names=True)
    reference = fmpy_result(fmu, 0.01, 1.0, table)
    np.testing.assert_allclose(written["x_m"], reference["x"], rtol=0, atol=TOLERANCE * np.abs(reference["x"]).max())


@pytest.mark.parametrize("text, reason", [
    ("time,f_in\n0.0,1.0\n0.5,nan\n", "line 3, column 'f_in': expected a finite number, got 'nan'"),
    ("time,f_in\n0.5,1.0\n0.0,1.0\n", "line 3: time 0.0 s is before the 0.5 s of line 2; expected times that do "
                                        "not decrease (column 'time')"),
    ("time,x\n0.0,1.0\n1.0,1.0\n", "column 'x' is not a real input of the FMI 2.0 Co-Simulation; expected one of "),
    ("time,f_in\n0.0,one\n1.0,2.0\n", "line 2, column 'f_in': expected a number, got 'one'"),
    ("time,f_in\n0.0,1.0\n", "1 row(s) of values; expected at least two"),
    ("time,f_in\n", "0 row(s) of values; expected at least two"),
    ("time,f_in\n0.0,1.0\n1.0\n", "line 3: 1 value(s), expected 2 (one per column: time, f_in)"),
    ("time,f_in\n0.0,1.0,2.0\n1.0,1.0\n", "line 2: 3 value(s), expected 2"),
    ("f_in,time\n1.0,0.0\n1.0,1.0\n", "line 1: the time must come first, got column 'f_in' first"),
    ("f_in,x\n1.0,0.0\n1.0,1.0\n", "line 1: the time must come first, got column 'f_in' first"),
    ("time\n0.0\n1.0\n", "line 1: expected the names of the time column and of at least one input variable"),
    ("time,f_in,f_in\n0,1,1\n1,1,1\n", "line 1: expected the names of the time column and of at least one input"),
    ("", "empty; expected a header line"),
    ("\xff\xfe\x00", "not text (UTF-8)"),
])
def test_a_bad_input_table_is_refused_naming_the_file_and_why(fmu, tmp_path, text, reason):
    table = tmp_path / "inputs.csv"
    table.write_bytes(text.encode("latin-1"))
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(fmu), {"input": str(table)})
    ((key, found),) = [(p.key, p.reason) for p in caught.value.problems]
    assert key == f"subsystems.{NAME}.input_table" and found.startswith(f"{table}: ") and reason in found, found


@pytest.mark.parametrize("source, said", [
    ("/dev/zero", "not a regular file; expected a CSV file"),
    ("folder", "not a regular file; expected a CSV file"),
    ("missing.csv", "no such file"),
    ("time,f_in\n0.0,1.0\n", "1 row(s) of values; expected at least two"),
    ("time,f_in\n0.0,1.0\n1.0\n", "line 3: 1 value(s), expected 2"),
])
def test_an_input_that_is_no_table_is_one_line_and_exit_2(fmu, tmp_path, source, said):
    """``zencosim run model.fmu --input …``: exit 2 naming the file and why, before anything runs."""
    (tmp_path / "folder").mkdir()
    if source == "/dev/zero" and not Path(source).exists():
        pytest.skip("no /dev/zero here")
    path = source if source.startswith("/") else str(tmp_path / source)
    if "\n" in source:
        path = str(tmp_path / "inputs.csv")
        Path(path).write_text(source)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        status = main(["run", str(fmu), "--input", path, "--quiet"])
    assert status == 2 and "Traceback" not in errors.getvalue(), errors.getvalue()
    assert f"subsystems.{NAME}.input_table: {path}: {said}" in " ".join(errors.getvalue().split())


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(alphabet="0123456789.,-e \ntimef_nax\"", max_size=60)
       | st.sampled_from(["time,f_in\n0,1\n2,3\n", "\"time\",\"f_in\"\n0,1e-3\n0,-2\n5.5,7\n"]))
def test_any_text_is_an_input_table_or_one_problem_naming_the_file(fmu, tmp_path, text):
    table = tmp_path / "inputs.csv"
    table.write_text(text)
    try:
        scene = zencosim.load_scene(str(fmu), {"input": str(table)})
    except zencosim.SceneError as error:
        ((key, found),) = [(p.key, p.reason) for p in error.problems]
        assert key == f"subsystems.{NAME}.input_table" and found.startswith(f"{table}: ")
    else:
        spec = scene.subsystems[NAME].spec.input_table
        assert spec.time.size >= 2 and np.all(np.diff(spec.time) >= 0) and np.all(np.isfinite(spec.values))
        assert spec.at(0.5).shape == (len(spec.variables),)
        if " " not in text and all(text.splitlines()):  # fmpy reads no blank line, and a space as a vector
            reference = fmpy.util.read_csv(table)  # the oracle: the columns fmpy.simulate_fmu would be given
            assert np.array_equal(reference[reference.dtype.names[0]], spec.time)
            assert all(np.array_equal(reference[n], v) for n, v in zip(spec.variables, spec.values))


def test_an_input_table_for_a_system_is_refused(tmp_path):
    system = tmp_path / "OspSystemStructure.xml"
    system.write_text("<OspSystemStructure/>")
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(system), {"input": "inputs.csv"})
    assert [p.key for p in caught.value.problems] == ["input"]


@pytest.mark.parametrize("tool, hint", [("zencosim.examples.fmus.build", False), ("pythonfmu 0.6.5", True)])
def test_an_fmu_that_cannot_be_instantiated_is_told_about_pythonfmu_only_when_pythonfmu_made_it(fmu, tmp_path,
                                                                                                 tool, hint):
    """A C FMU whose GUID does not match its binary's: fmpy's own reason; only an FMU whose generationTool is
    pythonfmu hears about the packages a Python FMU needs."""
    import re
    import zipfile
    broken = tmp_path / "broken.fmu"
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(broken, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                text = re.sub(r'guid="[^"]*"', 'guid="{00000000-0000-0000-0000-000000000000}"', data.decode())
                data = re.sub(r'generationTool="[^"]*"', f'generationTool="{tool}"', text).encode()
            target.writestr(item, data)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        status = main(["check", str(broken)])
    said = " ".join(errors.getvalue().split())
    assert status == 2 and "Traceback" not in said, said
    assert "FMU broken.fmu: cannot be instantiated (Exception: Failed to instantiate model); " in said
    assert ("a Python FMU (pythonfmu) needs its packages in this interpreter" in said) is hint
