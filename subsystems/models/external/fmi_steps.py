"""An FMU's communication step as one foreign call: ``fmi_steps.c``, compiled when first needed.

A co-simulation FMU's step as statements (``fmu.FmuCoSimulation.step_text``) sets the inputs, steps per micro-step
and gets the outputs: as one ctypes call per FMI call, about 3,700 instructions each (``benchmarks/bench_ffi.py``),
six per macro-step for two FMUs, where libcosim makes the same calls from C. ``fmi2_steps_run`` and
``fmi3_steps_run`` make those calls, with the same arguments and times, from a struct (:class:`FmiSteps`) that
points at the instance's preallocated arrays, so that a step is one call. They are compiled with the C compiler
(``$CC``, else ``cc`` or ``gcc``) into a temporary directory once per process (about 40 ms), loaded, and the file
removed. Where there is no compiler, or it fails, :func:`steps_function` is None: an FMI 2.0 FMU's calls are then
written one by one, and an FMI 3.0 FMU steps in the scheme's own loop.
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
TERMINATE = -1  # what a step returns when an FMI 3.0 FMU asked to terminate the simulation


class FmiSteps(ctypes.Structure):
    """``fmi_steps`` of ``fmi_steps.c``: what one communication step of an FMU calls, with what, and where it stopped
    (``failed_call``: 0 the inputs' set, 1 the step, 2 the outputs' get; ``failed_time`` [s])."""

    _fields_ = [("set", ctypes.c_void_p), ("do_step", ctypes.c_void_p), ("get", ctypes.c_void_p),
                ("instance", ctypes.c_void_p), ("inputs", ctypes.c_void_p), ("n_inputs", ctypes.c_size_t),
                ("u", ctypes.c_void_p), ("outputs", ctypes.c_void_p), ("n_outputs", ctypes.c_size_t),
                ("y", ctypes.c_void_p), ("h_ns", ctypes.c_longlong), ("h", ctypes.c_double),
                ("micro_steps", ctypes.c_longlong), ("failed_call", ctypes.c_longlong),
                ("failed_time", ctypes.c_double)]


def steps_function(version: str):
    """``fmi{version}_steps_run(fmi_steps *, long long start_ns) -> int`` (the failing status, ``TERMINATE``, else
    0) for FMI ``version`` ``"2"`` or ``"3"``; None where no C compiler is found or it fails."""
    library = _library()
    if library is None:
        return None
    function = library[f"fmi{version}_steps_run"]
    function.restype = ctypes.c_int
    return function


@functools.cache
def _library() -> ctypes.CDLL | None:
    """``fmi_steps.c`` compiled and loaded, once per process; None where no C compiler is found or it fails."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if compiler is None:
        return None
    source = resources.files("zencosim.subsystems.models.external").joinpath("fmi_steps.c").read_bytes()
    try:  # a temporary directory that cannot be written, or whose files cannot be mapped (noexec): none
        with tempfile.TemporaryDirectory(prefix="zencosim-fmi-") as directory:
            c_file, library = Path(directory) / "fmi_steps.c", Path(directory) / "fmi_steps.so"
            c_file.write_bytes(source)
            built = subprocess.run([compiler, "-O2", "-shared", "-fPIC", str(c_file), "-o", str(library)],
                                   capture_output=True, timeout=COMPILE_TIMEOUT_S, check=False)
            return ctypes.CDLL(str(library)) if built.returncode == 0 else None  # loaded: the file can go
    except (OSError, subprocess.TimeoutExpired):
        return None
