"""``fmi2_steps_run`` and ``fmi3_steps_run`` (``subsystems/models/external/fmi_steps.c``): an FMU's communication step
in one call makes the calls the generated loop's statements make one by one — set the inputs and step per micro-step
at ``t = (start + j h) × 1e-9`` s, get the outputs — stops at the first status worse than a warning, or where an FMI
3.0 FMU asks to terminate, and says which call stopped it and when; and where no C compiler is found, or it fails,
there is no such function (the calls go one by one).

The FMI functions here are a small C library compiled by the test, which records the calls and returns the statuses
it is given; the times it records are compared with Python's arithmetic of the same expression, bit for bit.
(tests/manager/test_compiled.py runs the example FMUs through the generated loop and compares every array with the
scheme's own loop.)"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import sys

import pytest

from zencosim.subsystems import native
from zencosim.subsystems.models.external.fmi_steps import TERMINATE, FmiSteps, steps_function

FAKE_FMI = r"""
#include <stdbool.h>
#include <stddef.h>
int fake_statuses[3];                    /* what the set, the step and the get return */
int fake_terminate;                      /* fmi3DoStep sets terminateSimulation */
int fake_calls[64], fake_n;              /* 0 set, 1 step, 2 get, in order */
double fake_times[64], fake_inputs[64];  /* the step's time; the last input set */
size_t fake_values[64];                  /* FMI 3.0: nValues of the set and the get */
static int set(const double *u, size_t n) {
    fake_calls[fake_n] = 0;
    fake_inputs[fake_n++] = u[n - 1];
    return fake_statuses[0];
}
static int step(double t) {
    fake_calls[fake_n] = 1;
    fake_times[fake_n++] = t;
    return fake_statuses[1];
}
static int get(const unsigned int *vr, size_t n, double *y) {
    size_t i;
    fake_calls[fake_n++] = 2;
    for (i = 0; i < n; i++) y[i] = 10.0 * vr[i];
    return fake_statuses[2];
}
int fake2_set(void *c, const unsigned int *vr, size_t n, const double *u) { return set(u, n); }
int fake2_step(void *c, double t, double h, int no_earlier) { return step(t); }
int fake2_get(void *c, const unsigned int *vr, size_t n, double *y) { return get(vr, n, y); }
int fake3_set(void *c, const unsigned int *vr, size_t n, const double *u, size_t values) {
    fake_values[fake_n] = values;
    return set(u, n);
}
int fake3_step(void *c, double t, double h, bool no_earlier, bool *event, bool *terminate, bool *early, double *last) {
    *terminate = fake_terminate;
    return step(t);
}
int fake3_get(void *c, const unsigned int *vr, size_t n, double *y, size_t values) {
    fake_values[fake_n] = values;
    return get(vr, n, y);
}
"""
START_NS, H_NS = 7_000_000_123, 333_333


@pytest.fixture(scope="module")
def fake(tmp_path_factory):
    """The fake FMI library, compiled (the step needs a C compiler, as the example FMUs do). Its names have a prefix:
    a global named as a libc symbol (``times``) would be libc's."""
    if shutil.which("gcc") is None or steps_function("2") is None:
        pytest.skip("fmi_steps needs a C compiler")
    directory = tmp_path_factory.mktemp("fake_fmi")
    (directory / "fake.c").write_text(FAKE_FMI)
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", str(directory / "fake.c"), "-o", str(directory / "fake.so")],
                   check=True)
    return ctypes.CDLL(str(directory / "fake.so"))


def _step(library, version: str, statuses: tuple[int, int, int], micro_steps: int, n_inputs: int = 2,
          n_outputs: int = 3, terminate: bool = False):
    """One step through ``fmi{version}_steps_run``: (status, the struct, the calls made, the steps' times, the
    inputs set, y, the nValues passed)."""
    (ctypes.c_int * 3).in_dll(library, "fake_statuses")[:] = statuses
    ctypes.c_int.in_dll(library, "fake_terminate").value = terminate
    ctypes.c_int.in_dll(library, "fake_n").value = 0
    inputs = (ctypes.c_uint * n_inputs)(*[4, 5][:n_inputs])
    outputs = (ctypes.c_uint * n_outputs)(*range(1, n_outputs + 1))
    u, y = (ctypes.c_double * n_inputs)(*(0.5 + i for i in range(n_inputs))), (ctypes.c_double * n_outputs)()
    address = ctypes.addressof

    def function(name: str) -> int:
        return ctypes.cast(getattr(library, f"fake{version}_{name}"), ctypes.c_void_p).value
    steps = FmiSteps(set=function("set"), do_step=function("step"), get=function("get"), instance=None,
                     inputs=address(inputs), n_inputs=n_inputs, u=address(u), outputs=address(outputs),
                     n_outputs=n_outputs, y=address(y), h_ns=H_NS, h=H_NS * 1e-9, micro_steps=micro_steps)
    status = steps_function(version)(ctypes.pointer(steps), ctypes.c_longlong(START_NS))
    n = ctypes.c_int.in_dll(library, "fake_n").value
    calls = list((ctypes.c_int * 64).in_dll(library, "fake_calls")[:n])
    times = list((ctypes.c_double * 64).in_dll(library, "fake_times")[:n])
    set_values = list((ctypes.c_double * 64).in_dll(library, "fake_inputs")[:n])
    values = list((ctypes.c_size_t * 64).in_dll(library, "fake_values")[:n])
    return status, steps, calls, [times[k] for k, call in enumerate(calls) if call == 1], \
        [set_values[k] for k, call in enumerate(calls) if call == 0], list(y), \
        [values[k] for k, call in enumerate(calls) if call != 1]


def _time(j: int) -> float:
    """The time of micro-step ``j`` as the statements compute it (``FmuCoSimulation.step_text``)."""
    return (START_NS + j * H_NS) * 1e-9


@pytest.mark.parametrize("version", ["2", "3"])
@pytest.mark.parametrize("micro_steps", [1, 3])
def test_a_step_sets_and_steps_per_micro_step_then_gets_at_the_statements_times(fake, version, micro_steps):
    status, _, calls, times, set_values, y, values = _step(fake, version, (0, 1, 1), micro_steps)  # warnings go on
    assert status == 0
    assert calls == [0, 1] * micro_steps + [2]
    assert times == [_time(j) for j in range(micro_steps)]
    assert set_values == [1.5] * micro_steps  # the last of the inputs
    assert y == [10.0, 20.0, 30.0]
    if version == "3":  # nValues: every variable a scalar
        assert values == [2] * micro_steps + [3]


@pytest.mark.parametrize("version", ["2", "3"])
def test_without_inputs_or_outputs_nothing_is_set_or_got(fake, version):
    status, _, calls, _, _, _, _ = _step(fake, version, (3, 0, 3), 2, n_inputs=0, n_outputs=0)
    assert (status, calls) == (0, [1, 1])


@pytest.mark.parametrize("version", ["2", "3"])
@pytest.mark.parametrize("statuses, failed_call, calls, time_j", [
    ((3, 0, 0), 0, [0], 0),  # the set: error
    ((0, 4, 0), 1, [0, 1], 0),  # the step: fatal, at the first micro-step
    ((0, 0, 3), 2, [0, 1, 0, 1, 2], 2),  # the get: error, at the step's end
], ids=["set", "step", "get"])
def test_the_first_failing_call_stops_the_step_and_says_which_and_when(fake, version, statuses, failed_call, calls,
                                                                       time_j):
    status, steps, made, _, _, _, _ = _step(fake, version, statuses, 2)
    assert status == max(statuses) and made == calls
    assert steps.failed_call == failed_call and steps.failed_time == _time(time_j)


def test_an_fmi3_fmu_that_asks_to_terminate_stops_the_step_at_that_micro_step(fake):
    status, steps, calls, _, _, _, _ = _step(fake, "3", (0, 0, 0), 3, terminate=True)
    assert (status, calls) == (TERMINATE, [0, 1])
    assert steps.failed_call == 1 and steps.failed_time == _time(0)


@pytest.mark.parametrize("environment", [{"CC": "/nonexistent/cc", "PATH": "/nonexistent"}, {"CC": "false"}],
                         ids=["no compiler", "a compiler that fails"])
def test_without_a_working_compiler_there_is_no_step_function(environment):
    """``steps_function`` is None (``step_text`` then writes a ctypes call per FMI call, or leaves an FMI 3.0 FMU to
    the scheme's own loop), never an error."""
    program = ("from zencosim.subsystems.models.external.fmi_steps import steps_function; "
               "print(steps_function('2'), steps_function('3'))")
    result = subprocess.run([sys.executable, "-c", program], env={**os.environ, **environment}, capture_output=True,
                            text=True, check=True)
    assert result.stdout.strip() == "None None"


@pytest.mark.parametrize("where, error", [("tempfile.TemporaryDirectory", PermissionError(13, "Permission denied")),
                                          ("ctypes.CDLL", OSError("failed to map segment from shared object"))],
                         ids=["no writable temporary directory", "a temporary directory mounted noexec"])
def test_where_the_compiled_step_cannot_be_written_or_loaded_there_is_none(where, error, monkeypatch, tmp_path):
    """A temporary directory that cannot be written, or whose files cannot be mapped to run (``noexec``): None, as
    without a compiler, not an error that ends the run (with nothing in the cache to load instead)."""
    monkeypatch.setenv(native.CACHE_DIR, str(tmp_path / "empty cache"))
    module, name = where.split(".")

    def fails(*args, **kwargs):
        raise error
    monkeypatch.setattr(getattr(native, module), name, fails)
    native.library.cache_clear()
    try:
        assert steps_function("2") is None and steps_function("3") is None
    finally:
        monkeypatch.undo()
        native.library.cache_clear()  # the next caller compiles it again


@pytest.mark.multiprocess
def test_an_fmu_run_without_a_compiler_says_once_at_its_start_that_its_steps_are_slower(examples):
    """Where the compiled step cannot be had, ``zencosim run`` says so in its first line, once (the command says it
    before it starts the run's processes, which say nothing), names the FMUs, and the run goes on; with the
    compiler, nothing is said."""
    def run(environment: dict) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "zencosim", "run", str(examples / "two_mass_damped_fmu.toml"),
                               "--set", "manager.duration=0.05"], env=environment, capture_output=True,
                              text=True, timeout=120)
    without, compiled = run({**os.environ, "CC": "/nonexistent/cc", "PATH": "/nonexistent"}), run(dict(os.environ))
    assert without.returncode == 0 and compiled.returncode == 0, without.stderr + compiled.stderr
    assert without.stderr.startswith("no working C compiler ($CC, else cc or gcc): each step of FMUs S1, S2 is a "
                                     "ctypes call per FMI call from Python, several times slower"), without.stderr
    assert without.stderr.count("C compiler") == 2  # the note's own two mentions, in one line
    assert "C compiler" not in compiled.stderr
