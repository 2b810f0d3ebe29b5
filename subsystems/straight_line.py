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

import numpy as np

MAX_TERMS = 200  # products per step; at about 25 ns each in CPython, beyond this numpy's four calls are cheaper

StraightLineStep = Callable[[np.ndarray, list[float]], tuple[list[float], list[float]]]


def straight_line_step(Phi_m: np.ndarray, Psi: np.ndarray, rows: int, span_s: float, G: np.ndarray, n_linear: int,
                       y_0: np.ndarray | None) -> StraightLineStep | None:
    """``step(z, c) -> (y, w)``: advance the state ``z`` (float64 array, updated in place) over one communication
    step of ``span_s`` seconds with the flattened coefficients ``c`` (``rows`` rows of the inputs, a list of
    floats), returning the outputs ``y`` (``n_linear`` linear outputs, then the energy) and the input values ``w``
    at the step's end, both lists of floats. ``Psi`` is flattened to ``(n_state, rows × n_inputs)``, ``G`` is
    ``[G_y; Q/2]`` over ``s = [z, w]``, ``y_0`` the constant output offsets (None: none). None when the step has
    more than ``MAX_TERMS`` products or a non-finite entry."""
    n_state = Phi_m.shape[0]
    n_inputs = Psi.shape[1] // rows
    terms = sum(np.count_nonzero(m) for m in (Phi_m, Psi, G))
    finite = all(np.isfinite(m).all() for m in (Phi_m, Psi, G)) and math.isfinite(span_s)
    if terms > MAX_TERMS or not finite or (y_0 is not None and not np.isfinite(y_0).all()):
        return None
    z_names = [f"z{i}" for i in range(n_state)]
    c_names = [f"c{i}" for i in range(rows * n_inputs)]
    lines = ["def step(z, c):"]
    if n_state:
        lines.append(f"    {_unpacked(z_names)} = z.tolist()")
    if c_names:
        lines.append(f"    {_unpacked(c_names)} = c")
    for i in range(n_state):
        lines.append(f"    n{i} = " + _sum(Phi_m[i], z_names, Psi[i], c_names))
    for i in range(n_state):
        lines.append(f"    z[{i}] = n{i}")
    w_names = []
    for j in range(n_inputs):  # at τ_end, as InputPolynomial.at evaluates it
        value = _horner(rows, n_inputs, j, span_s) if rows > 1 else f"c{j}"
        lines.append(f"    w{j} = {value}")
        w_names.append(f"w{j}")
    s_names = [f"n{i}" for i in range(n_state)] + w_names
    outputs = []
    for row in range(n_linear):
        value = _sum(G[row], s_names)
        if y_0 is not None:
            value = f"({value}) + {float(y_0[row])!r}"
        lines.append(f"    y{row} = {value}")
        outputs.append(f"y{row}")
    quadratic = [(i, _sum(G[n_linear + i], s_names)) for i in range(len(s_names)) if np.any(G[n_linear + i])]
    for i, value in quadratic:
        lines.append(f"    q{i} = {value}")
    lines.append("    energy = " + (" + ".join(f"q{i} * {s_names[i]}" for i, _ in quadratic) or "0.0"))
    lines.append(f"    return [{', '.join(outputs + ['energy'])}], [{', '.join(w_names)}]")
    namespace: dict = {}
    exec(compile("\n".join(lines) + "\n", "<straight-line step>", "exec"), namespace)  # noqa: S102 (our own text)
    return namespace["step"]


def _horner(rows: int, n_inputs: int, j: int, span_s: float) -> str:
    """Input ``j`` at ``span_s``: ``((c_o τ + c_{o-1}) τ + …) τ + c_0`` with ``c_r`` the flat name ``c{r n + j}``."""
    value = f"c{(rows - 1) * n_inputs + j} * {span_s!r}"
    for r in range(rows - 2, 0, -1):
        value = f"(({value}) + c{r * n_inputs + j}) * {span_s!r}"
    return f"({value}) + c{j}"


def _sum(*factors_and_names) -> str:
    """``Σ a_i x_i`` over the non-zero ``a_i`` of each (coefficients, names) pair in turn, left to right; "0.0" for
    none."""
    terms = [f"{float(a)!r} * {name}" for coefficients, names in zip(factors_and_names[::2], factors_and_names[1::2])
             for a, name in zip(coefficients, names) if a != 0.0]
    return " + ".join(terms) or "0.0"


def _unpacked(names: list[str]) -> str:
    """The target of an unpacking assignment (a one-element one needs its comma)."""
    return ", ".join(names) + ("," if len(names) == 1 else "")
