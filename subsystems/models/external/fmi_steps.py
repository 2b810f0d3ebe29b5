"""An FMU's communication step as one foreign call: ``fmi_steps.c``, compiled when first needed.

A co-simulation FMU's step as statements (``fmu.FmuCoSimulation.step_text``) sets the inputs, steps per micro-step
and gets the outputs: as one ctypes call per FMI call, about 3,700 instructions each (``benchmarks/bench_ffi.py``),
six per macro-step for two FMUs, where libcosim makes the same calls from C. ``fmi2_steps_run`` and
``fmi3_steps_run`` make those calls, with the same arguments and times, from a struct (:class:`FmiSteps`) that
points at the instance's preallocated arrays, so that a step is one call: from the generated Python loop, or from
the register program that runs the loop in C (``manager.scheme.register_loop``, a native step, with no Python
between two steps). They are compiled with the C compiler when first needed (``subsystems.native``). Where there
is no compiler, or it fails, :func:`steps_function` is None: an FMI 2.0 FMU's calls are then written one by one,
and an FMI 3.0 FMU steps in the scheme's own loop.
"""
from __future__ import annotations

import ctypes
from collections.abc import Mapping

from zencosim.subsystems.native import library

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
    compiled = library("zencosim.subsystems.models.external", "fmi_steps.c")
    if compiled is None:
        return None
    function = compiled[f"fmi{version}_steps_run"]
    function.restype = ctypes.c_int
    return function


def uncompiled_fmus(specs: Mapping[str, object]) -> list[str]:
    """The co-simulation FMUs among ``specs`` (subsystem name → spec) whose communication step cannot be one compiled
    call here (:func:`steps_function` None: no C compiler, or it fails): each of their steps is then a ctypes call
    per FMI call from Python, several times slower (docs/models.md). Empty where every step is compiled."""
    fmus = [name for name, spec in specs.items()
            if getattr(spec, "reference", None) == "fmu" and getattr(spec, "advances_itself", False)]
    return fmus if fmus and steps_function("2") is None else []
