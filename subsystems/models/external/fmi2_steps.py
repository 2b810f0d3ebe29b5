"""An FMI 2.0 FMU's communication step as one foreign call: ``fmi2_steps.c``, compiled when first needed.

A co-simulation FMU's step as statements (``fmu.FmuCoSimulation.step_text``) sets the inputs, calls ``fmi2DoStep``
per micro-step and gets the outputs: one ctypes call per FMI call, about 4,000 instructions each
(``benchmarks/bench_ffi.py``), six per macro-step for two FMUs, where libcosim makes the same calls from C. The C
function ``fmi2_steps_run`` makes those calls, with the same arguments and times, from a struct (:class:`Fmi2Steps`)
that points at the instance's preallocated arrays, so that a step is one call. It is compiled with the C compiler
(``$CC``, else ``cc`` or ``gcc``) into a temporary directory once per process (about 40 ms), loaded and the file
removed. Where there is no compiler, or it fails, :func:`steps_function` is None and the step's calls are made one by
one, as before.
"""
from __future__ import annotations

import ctypes
import functools
import os
import shutil
import subprocess
import tempfile
from importlib import resources
from pathlib import Path

COMPILE_TIMEOUT_S = 120  # a compiler still running after this long is given up on: the calls go one by one


class Fmi2Steps(ctypes.Structure):
    """``fmi2_steps`` of ``fmi2_steps.c``: what one communication step of an FMU calls, with what, and where it
    failed (``failed_call``: 0 ``fmi2SetReal``, 1 ``fmi2DoStep``, 2 ``fmi2GetReal``; ``failed_time`` [s])."""

    _fields_ = [("set_real", ctypes.c_void_p), ("do_step", ctypes.c_void_p), ("get_real", ctypes.c_void_p),
                ("instance", ctypes.c_void_p), ("inputs", ctypes.c_void_p), ("n_inputs", ctypes.c_size_t),
                ("u", ctypes.c_void_p), ("outputs", ctypes.c_void_p), ("n_outputs", ctypes.c_size_t),
                ("y", ctypes.c_void_p), ("h_ns", ctypes.c_longlong), ("h", ctypes.c_double),
                ("micro_steps", ctypes.c_longlong), ("failed_call", ctypes.c_longlong),
                ("failed_time", ctypes.c_double)]


@functools.cache
def steps_function():
    """``fmi2_steps_run(fmi2_steps *, long long start_ns) -> int`` (the failing status, else 0), compiled once per
    process; None where no C compiler is found or it fails."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if compiler is None:
        return None
    source = resources.files("zencosim.subsystems.models.external").joinpath("fmi2_steps.c").read_bytes()
    with tempfile.TemporaryDirectory(prefix="zencosim-fmi2-") as directory:
        c_file, library = Path(directory) / "fmi2_steps.c", Path(directory) / "fmi2_steps.so"
        c_file.write_bytes(source)
        try:
            built = subprocess.run([compiler, "-O2", "-shared", "-fPIC", str(c_file), "-o", str(library)],
                                   capture_output=True, timeout=COMPILE_TIMEOUT_S, check=False)
        except (OSError, subprocess.TimeoutExpired):
            return None
        if built.returncode != 0:
            return None
        function = ctypes.CDLL(str(library)).fmi2_steps_run  # loaded: the file can go
    function.restype = ctypes.c_int
    return function
