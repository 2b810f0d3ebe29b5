"""The register program (``manager.scheme.register_loop``): statements of float arithmetic run in C leave every name
with the value Python's own arithmetic gives it, bit for bit; what is not float arithmetic, or a machine without a C
compiler, gives no program (the Python loop runs); each step's release time is read from Python's clock.

The oracle is Python running the same statements."""
from __future__ import annotations

import math
import os
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.scheme.register_loop import STAMP_STATEMENT, register_loop

NAMES = ["a", "b", "c", "d"]
floats = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([0.0, -0.0, 5e-324, 1e308, -1e308])


def _literal(value: float) -> str:
    """A float as a statement writes it (a negative one as Python's folded unary minus; inf and nan as products
    that overflow, which are float arithmetic too)."""
    if math.isnan(value):
        return "(1e308 * 10.0 - 1e308 * 10.0)"
    if math.isinf(value):
        return "(1e308 * 10.0)" if value > 0 else "(-1e308 * 10.0)"
    return repr(value)


@st.composite
def expressions(draw, depth: int = 3) -> str:
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(st.sampled_from(NAMES)) if draw(st.booleans()) else _literal(draw(floats))
    kind = draw(st.sampled_from(["+", "-", "*", "neg"]))
    if kind == "neg":
        return f"-({draw(expressions(depth - 1))})"
    return f"({draw(expressions(depth - 1))}) {kind} ({draw(expressions(depth - 1))})"


def _bits(values) -> list[bytes]:
    """Each value's bits; every NaN as one: CPython gives a sum or product of two NaNs the right one's sign in its
    first executions of the statement and the left one's once the operation is specialized (measured), so no NaN's
    sign is Python's to give, and the register program takes the left one's always (``register_loop.c``)."""
    return [b"nan" if math.isnan(value) else struct.pack("<d", value) for value in values]


def _python(initial: dict[str, float], statements: list[str], steps: int) -> tuple[dict, list[list[float]]]:
    names, rows = dict(initial), []
    for _ in range(steps):
        for statement in statements:
            exec(statement, {}, names)  # our own generated text
        rows.append([names[name] for name in NAMES])
    return names, rows


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(NAMES), expressions()), min_size=1, max_size=8),
       st.lists(floats, min_size=4, max_size=4), st.integers(1, 4))
def test_a_register_program_leaves_every_name_as_python_does_bit_for_bit(assignments, values, steps):
    """Generated statements of sums, differences, products and negations of names and constants (signed zeros,
    subnormals, infinities, NaN, overflow), a name assigned from itself, run for a few steps: every name and every
    row the same bits as Python's."""
    statements = [f"{name} = {expression}" for name, expression in assignments]
    program = register_loop(NAMES, statements, NAMES)
    assert program is not None
    program.set(NAMES, values)
    rows, _ = program.steps(steps)
    expected, expected_rows = _python(dict(zip(NAMES, values)), statements, steps)
    assert _bits(program.get(NAMES)) == _bits(expected[name] for name in NAMES)
    assert [_bits(row) for row in rows.tolist()] == [_bits(row) for row in expected_rows]


@pytest.mark.parametrize("statement", ["a = b / c", "a = f(b)", "a = b ** 2.0", "a = 2 * b", "a = b.real",
                                       "a, b = c, d", "a = e * 2.0", "a += b", "print(a)"],
                         ids=["division", "call", "power", "integer", "attribute", "unpacking", "unknown name",
                              "augmented", "expression"])
def test_what_is_not_float_arithmetic_gives_no_program(statement):
    """A division (Python raises where C gives an infinity), a call (an FMU's step), an integer, a name read before
    it is set, ...: None, and the Python loop runs."""
    assert register_loop(NAMES, [statement], NAMES) is None


def test_a_row_of_a_name_never_set_gives_no_program():
    assert register_loop(NAMES, ["a = b"], ["a", "e"]) is None


def test_signed_zeros_are_two_constants():
    """0.0 and -0.0 compare equal but are different constants: each keeps its sign."""
    program = register_loop(NAMES, ["a = 0.0 * b", "c = -0.0 * b", "d = -0.0"], NAMES)
    program.set(NAMES, [9.0, 1.0, 9.0, 9.0])
    program.steps(1)
    assert _bits(program.get(NAMES)) == _bits([0.0, 1.0, -0.0, -0.0])


def test_of_two_nans_the_left_ones_sign_is_kept():
    """What the register program decides where Python does not (see ``_bits``): the left operand's NaN, as CPython's
    specialized operations and numpy give it."""
    negative, positive = -math.nan, math.nan
    program = register_loop(NAMES, ["c = a + b", "d = b * a", "b = a - b"], NAMES)
    program.set(NAMES, [negative, positive, 0.0, 0.0])
    program.steps(1)
    assert [math.copysign(1.0, value) for value in program.get(NAMES)] == [-1.0, -1.0, -1.0, 1.0]


def test_each_steps_release_time_is_read_from_pythons_perf_counter():
    """STAMP reads CLOCK_MONOTONIC, ``time.perf_counter_ns``'s clock: the times lie between two readings of it,
    in order, one per step."""
    program = register_loop(NAMES, [STAMP_STATEMENT, "a = a + 1.0"], NAMES)
    before = time.perf_counter_ns()
    rows, times = program.steps(1000)
    after = time.perf_counter_ns()
    assert before <= times[0] and times[-1] <= after and (np.diff(times) >= 0).all()
    assert rows[:, 0].tolist() == [float(k) for k in range(1, 1001)]


def test_without_a_working_compiler_there_is_no_program():
    program = ("from zencosim.manager.scheme.register_loop import register_loop; "
               "print(register_loop(['a'], ['a = a * 2.0'], ['a']))")
    result = subprocess.run([sys.executable, "-c", program], env={**os.environ, "CC": "false"}, capture_output=True,
                            text=True, check=True)
    assert result.stdout.strip() == "None"
