"""Instructions per foreign call from Python into a C FMU, counted by valgrind: what two C FMUs cost per step.

    python benchmarks/bench_ffi.py [--json out.json]

zencosim stepped a co-simulation FMU with one foreign call per FMI call, six per macro-step for two FMUs, where
libcosim makes the same six calls from C; it now makes a step's calls in one foreign call where a C compiler is at
hand (``subsystems/models/external/fmi_steps.c``). This counts what each way costs.
The example FMU (``zencosim examples``) is opened as ``two_mass_damped_fmu.toml``'s subsystem S2; each figure is
the difference of two runs under ``valgrind --tool=cachegrind`` (``CALLS`` apart) per iteration of a loop in a
function, less the same loop with nothing in it:

* ``ctypes``: ``fmi2GetReal`` as zencosim calls it (a bare handle, its C arguments built once: ``fmu._bare``);
* ``pydll``: the same handle loaded through ``ctypes.PyDLL``, which keeps the GIL during the call;
* ``cffi``: the same call in cffi's ABI mode (where cffi is installed);
* ``step``: one FMU step as the generated loop makes it: set the inputs, ``fmi2DoStep``, get the outputs;
* ``step_glue``: the same three calls as the generated Python loop makes them, one call of ``fmi2_steps_run``
  (``subsystems/models/external/fmi_steps.c``, compiled at first use); where the loop runs as a register program,
  that call is made from C (``manager/scheme/register_loop.c``: ``bench_instructions.py --fmu`` counts it);
* ``step_numba``: the same three calls compiled into one numba function, the FMU's addresses passed as integers
  (where numba is installed; its import and compilation, the same in both runs, cancel out).

Needs valgrind, gcc and fmpy.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from bench_instructions import counted

CALLS = (1_000, 21_000)
ONE_RUN = """
import ctypes, sys
from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene

what, n = sys.argv[1], int(sys.argv[2])
_, subsystems = plan_scene(load_scene(sys.argv[3] + "/two_mass_damped_fmu.toml"))
fmu = subsystems["S2"].model.instance
get, get_arguments = fmu._get, fmu._get_arguments


def empty(n):
    for _ in range(n):
        pass


def calls(call, arguments, n):
    for _ in range(n):
        call(*arguments)


def steps(n):
    set_real, set_arguments, do_step, instance = fmu._set, fmu._set_arguments, fmu._step, fmu._instance
    time, h, false = ctypes.c_double(), ctypes.c_double(1e-3), ctypes.c_int(0)
    for tick in range(n):
        set_real(*set_arguments)
        time.value = tick * 1e-3
        do_step(instance, time, h, false)
        get(*get_arguments)


def glue_steps(n):
    namespace = fmu.step_text("p_", "0", 1, 1_000_000).namespace
    run_steps, steps, start = namespace["p_run_steps"], namespace["p_steps"], namespace["p_start"]
    for tick in range(n):
        start.value = tick * 1_000_000
        run_steps(steps, start)


def numba_steps(n):
    from numba import njit
    word = ctypes.c_uint64  # a pointer, passed as the integer it is (the same register on 64-bit platforms)

    def handle(name, *arguments):
        return ctypes.CFUNCTYPE(ctypes.c_int, *arguments)(ctypes.cast(fmu.fmu.dll[name], ctypes.c_void_p).value)
    set_real, get_real = (handle(name, word, word, ctypes.c_size_t, word) for name in ("fmi2SetReal", "fmi2GetReal"))
    do_step = handle("fmi2DoStep", word, ctypes.c_double, ctypes.c_double, ctypes.c_int)

    @njit
    def step(instance, inputs, n_inputs, u, outputs, n_outputs, y, t, h):
        status = set_real(instance, inputs, n_inputs, u)
        status = max(status, do_step(instance, t, h, 0))
        return max(status, get_real(instance, outputs, n_outputs, y))
    address = ctypes.addressof
    arguments = (fmu.fmu.component, address(fmu._inputs), len(fmu._inputs), address(fmu._u), address(fmu._outputs),
                 len(fmu._outputs), address(fmu._y))
    for tick in range(n):
        step(*arguments, tick * 1e-3, 1e-3)


if what == "empty":
    empty(n)
elif what == "ctypes":
    calls(get, get_arguments, n)
elif what == "pydll":
    handle = ctypes.PyDLL(fmu.fmu.dll._name)["fmi2GetReal"]
    handle.restype = ctypes.c_int
    calls(handle, get_arguments, n)
elif what == "cffi":
    import cffi
    ffi = cffi.FFI()
    ffi.cdef("int fmi2GetReal(void *, const unsigned int *, size_t, double *);")
    call = ffi.dlopen(fmu.fmu.dll._name).fmi2GetReal
    calls(call, (ffi.cast("void *", fmu.fmu.component), ffi.from_buffer("unsigned int[]", fmu._outputs),
                 len(fmu._outputs), ffi.from_buffer("double[]", fmu._y)), n)
elif what == "step":
    steps(n)
elif what == "step_glue":
    glue_steps(n)
else:
    numba_steps(n)
"""
OPTIONAL = {"cffi": "cffi", "step_numba": "numba"}  # kinds counted only where their package is installed
LABELS = {"ctypes": "fmi2GetReal through ctypes, as zencosim calls it",
          "pydll": "the same through ctypes.PyDLL (GIL kept)", "cffi": "the same in cffi's ABI mode",
          "step": "one FMU step: set, fmi2DoStep, get (three ctypes calls)",
          "step_glue": "the same three calls as one call of fmi2_steps_run (the Python loop's)",
          "step_numba": "the same three calls in one numba function"}


def instructions(what: str, calls: int, directory: str) -> int:
    return counted(ONE_RUN, [what, str(calls), directory], os.environ.get("PYTHONPATH", ""),
                   f"bench_ffi: {what} of {calls} calls")


def per_iteration(what: str, directory: str) -> float:
    low, high = (instructions(what, n, directory) for n in CALLS)
    return (high - low) / (CALLS[1] - CALLS[0])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    if shutil.which("valgrind") is None:
        print("bench_ffi needs valgrind (apt-get install valgrind)", file=sys.stderr)
        return 2
    from importlib.util import find_spec

    from zencosim.examples.write import write_examples
    figures = {}
    with tempfile.TemporaryDirectory() as directory:
        write_examples(Path(directory))
        empty = per_iteration("empty", directory)
        for what, label in LABELS.items():
            if what in OPTIONAL and find_spec(OPTIONAL[what]) is None:
                print(f"{label}: not counted ({OPTIONAL[what]} is not installed)", flush=True)
                continue
            figures[what] = per_iteration(what, directory) - empty
            print(f"{label:60} {figures[what]:8.0f} instructions", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
