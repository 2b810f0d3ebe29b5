"""A small linear subsystem's communication step as one straight-line Python function over floats (issue 26).

A linear, time-invariant model under a linear integrator advances by its composed step and gives its outputs as
one matrix product (``subsystems.subsystem``; ``subsystems.integrators.base.composed_linear_step``)::

    z ← Φ^m z + Ψ c,   s = [z, w(τ_end)],   y = G_y s + y_0,   E = s · (Q/2) s

with ``c`` the input polynomial's coefficients row after row and ``w(τ_end)`` the polynomial at the step's end
(Horner's scheme, as ``InputPolynomial.at``). For the papers' few-body subsystems numpy's cost per call, four
calls a step, is most of the step: the same products written out term by term, each matrix entry a literal and
exact zeros left out, take a tenth of it. They differ from numpy's products by rounding only (the order of a
row's sum; OpenBLAS may fuse multiply and add). A subsystem whose step has more than ``MAX_TERMS`` products, or
a non-finite entry, keeps numpy's products (``straight_line_step`` gives None): there the per-term cost of
Python outweighs numpy's per-call cost.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

MAX_TERMS = 200  # products per step; at about 25 ns each in CPython, beyond this numpy's four calls are cheaper

StraightLineStep = Callable[[np.ndarray, list[float]], tuple[list[float], list[float]]]


@dataclass(frozen=True)
class NativeStep:
    """A step that a compiled function makes in one call, ``int function(void *argument, long long start_ns)`` (an
    FMU's, ``subsystems.models.external.fmi_steps``), for a loop that runs the steps in C
    (``manager.scheme.register_loop``): the step's inputs written into the array ``u`` before the call, its outputs
    read from ``y`` after it, and a nonzero status the model's failure, ``failure(status)``. In a watched run the
    call is marked on the watch's page ``marks`` as subsystem number ``mark`` (``manager.bus.watchdog``)."""

    function: object  # a ctypes function
    argument: object  # a ctypes object, passed by reference
    u: object  # ctypes arrays of doubles
    y: object
    failure: Callable[[int], BaseException]
    marks: object = None  # a writable buffer of int64 slots: ``ModelWatch.slots``
    mark: int = -1


@dataclass(frozen=True)
class StepText:
    """A subsystem's step as statements over float names with one prefix: it reads the state ``state`` and the
    input coefficients ``coefficients`` (row after row) and leaves the state at the step's end in ``new_state``, the
    input values there in ``inputs_at_end`` and the outputs in ``outputs`` (a linear model's: the linear ones, then
    the energy). ``namespace``: the objects the statements call, by their (prefixed) names (a model's own step:
    ``subsystems.models.external.fmu``). ``native``: the same step as one call of a compiled function, where it is
    one (the statements then make that call)."""

    statements: tuple[str, ...]
    state: tuple[str, ...]
    coefficients: tuple[str, ...]
    new_state: tuple[str, ...]
    inputs_at_end: tuple[str, ...]
    outputs: tuple[str, ...]
    namespace: dict = field(default_factory=dict)
    native: NativeStep | None = None


def step_text(Phi_m: np.ndarray, Psi: np.ndarray, rows: int, span_s: float, G: np.ndarray, n_linear: int,
              y_0: np.ndarray | None, prefix: str = "") -> StepText | None:
    """The statements of the step ``straight_line_step`` makes a function of, each name prefixed with ``prefix`` (a
    generated scene loop holds several subsystems' steps: ``manager.scheme.compiled``); None when the step has more
    than ``MAX_TERMS`` products or a non-finite entry."""
    n_state = Phi_m.shape[0]
    n_inputs = Psi.shape[1] // rows
    terms = sum(np.count_nonzero(m) for m in (Phi_m, Psi, G))
    finite = all(np.isfinite(m).all() for m in (Phi_m, Psi, G)) and math.isfinite(span_s)
    if terms > MAX_TERMS or not finite or (y_0 is not None and not np.isfinite(y_0).all()):
        return None
    z_names = [f"{prefix}z{i}" for i in range(n_state)]
    c_names = [f"{prefix}c{i}" for i in range(rows * n_inputs)]
    n_names = [f"{prefix}n{i}" for i in range(n_state)]
    lines = [f"{n_names[i]} = " + _sum(Phi_m[i], z_names, Psi[i], c_names) for i in range(n_state)]
    w_names = []
    for j in range(n_inputs):  # at τ_end, as InputPolynomial.at evaluates it
        w_names.append(f"{prefix}w{j}")
        lines.append(f"{w_names[-1]} = " + (_horner(c_names, rows, n_inputs, j, span_s) if rows > 1 else c_names[j]))
    s_names = n_names + w_names
    outputs = []
    for row in range(n_linear):
        value = _sum(G[row], s_names)
        if y_0 is not None:
            value = f"({value}) + {float(y_0[row])!r}"
        outputs.append(f"{prefix}y{row}")
        lines.append(f"{outputs[-1]} = {value}")
    quadratic = [(f"{prefix}q{i}", i) for i in range(len(s_names)) if np.any(G[n_linear + i])]
    lines.extend(f"{q} = {_sum(G[n_linear + i], s_names)}" for q, i in quadratic)
    outputs.append(f"{prefix}energy")
    lines.append(f"{outputs[-1]} = " + (" + ".join(f"{q} * {s_names[i]}" for q, i in quadratic) or "0.0"))
    return StepText(tuple(lines), tuple(z_names), tuple(c_names), tuple(n_names), tuple(w_names), tuple(outputs))


def straight_line_step(Phi_m: np.ndarray, Psi: np.ndarray, rows: int, span_s: float, G: np.ndarray, n_linear: int,
                       y_0: np.ndarray | None) -> StraightLineStep | None:
    """``step(z, c) -> (y, w)``: advance the state ``z`` (float64 array, updated in place) over one communication
    step of ``span_s`` seconds with the flattened coefficients ``c`` (``rows`` rows of the inputs, a list of
    floats), returning the outputs ``y`` (``n_linear`` linear outputs, then the energy) and the input values ``w``
    at the step's end, both lists of floats. ``Psi`` is flattened to ``(n_state, rows × n_inputs)``, ``G`` is
    ``[G_y; Q/2]`` over ``s = [z, w]``, ``y_0`` the constant output offsets (None: none). None when the step has
    more than ``MAX_TERMS`` products or a non-finite entry."""
    text = step_text(Phi_m, Psi, rows, span_s, G, n_linear, y_0)
    if text is None:
        return None
    lines = ["def step(z, c):", *body_lines(text, "z.tolist()", "c")]
    lines.extend(f"    z[{i}] = {name}" for i, name in enumerate(text.new_state))
    lines.append(f"    return [{', '.join(text.outputs)}], [{', '.join(text.inputs_at_end)}]")
    return define("\n".join(lines), "step", "<straight-line step>")


def body_lines(text: StepText, state: str, coefficients: str) -> list[str]:
    """A generated function's lines that run ``text``'s statements (indented once): its state names unpacked from the
    expression ``state``, its coefficient names from ``coefficients``, then the statements."""
    lines = []
    if text.state:
        lines.append(f"    {unpacked(text.state)} = {state}")
    if text.coefficients:
        lines.append(f"    {unpacked(text.coefficients)} = {coefficients}")
    return lines + [f"    {statement}" for statement in text.statements]


def define(source: str, name: str, label: str, namespace: dict | None = None):
    """The function ``name`` that ``source`` (our own generated text) defines, compiled under ``label``, its globals
    ``namespace``."""
    namespace = {} if namespace is None else namespace
    exec(compile(source + "\n", label, "exec"), namespace)  # noqa: S102 (our own text)
    return namespace[name]


def _horner(c_names: list[str], rows: int, n_inputs: int, j: int, span_s: float) -> str:
    """Input ``j`` at ``span_s``: ``((c_o τ + c_{o-1}) τ + …) τ + c_0``, ``c_r`` the flat name ``c_names[r n + j]``."""
    value = f"{c_names[(rows - 1) * n_inputs + j]} * {span_s!r}"
    for r in range(rows - 2, 0, -1):
        value = f"(({value}) + {c_names[r * n_inputs + j]}) * {span_s!r}"
    return f"({value}) + {c_names[j]}"


def _sum(*factors_and_names) -> str:
    """``Σ a_i x_i`` over the non-zero ``a_i`` of each (coefficients, names) pair in turn, left to right; "0.0" for
    none."""
    terms = [f"{float(a)!r} * {name}" for coefficients, names in zip(factors_and_names[::2], factors_and_names[1::2])
             for a, name in zip(coefficients, names) if a != 0.0]
    return " + ".join(terms) or "0.0"


def unpacked(names: tuple[str, ...]) -> str:
    """The target of an unpacking assignment (a one-element one needs its comma)."""
    return ", ".join(names) + ("," if len(names) == 1 else "")
