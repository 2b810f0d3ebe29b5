"""The register program (``manager.scheme.register_loop``): statements of float arithmetic run in C leave every name
with the value Python's own arithmetic gives it, bit for bit; what is not float arithmetic, or a machine without a C
compiler, gives no program (the Python loop runs); each step's release time is read from Python's clock.

The oracle is Python running the same statements."""
from __future__ import annotations

import ctypes
import math
import os
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zencosim.manager.scheme.register_loop as register_loop_module
from zencosim.manager.bus.watchdog import CALLS, STEPPING, SUBSYSTEM, ModelWatch
from zencosim.manager.scheme.register_loop import STAMP_STATEMENT, Failed, NativeCall, register_loop
from zencosim.subsystems.native import FLAGS, c_compiler
from zencosim.subsystems.straight_line import NativeStep

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
    rows, _, _ = program.steps(0, steps)
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
    program.steps(0, 1)
    assert _bits(program.get(NAMES)) == _bits([0.0, 1.0, -0.0, -0.0])


def test_of_two_nans_the_left_ones_sign_is_kept():
    """What the register program decides where Python does not (see ``_bits``): the left operand's NaN, as CPython's
    specialized operations and numpy give it."""
    negative, positive = -math.nan, math.nan
    program = register_loop(NAMES, ["c = a + b", "d = b * a", "b = a - b"], NAMES)
    program.set(NAMES, [negative, positive, 0.0, 0.0])
    program.steps(0, 1)
    assert [math.copysign(1.0, value) for value in program.get(NAMES)] == [-1.0, -1.0, -1.0, 1.0]


def test_each_steps_release_time_is_read_from_pythons_perf_counter(monkeypatch):
    """STAMP reads CLOCK_MONOTONIC, ``time.perf_counter_ns``'s clock: the times lie between two readings of it,
    in order, one per step. All 1,000 come in one block: float arithmetic alone has no time budget, even one that
    every step exceeds."""
    monkeypatch.setattr(register_loop_module, "BUDGET_NS", -1)
    program = register_loop(NAMES, [STAMP_STATEMENT, "a = a + 1.0"], NAMES)
    before = time.perf_counter_ns()
    rows, times, _ = program.steps(0, 1000)
    after = time.perf_counter_ns()
    assert before <= times[0] and times[-1] <= after and (np.diff(times) >= 0).all()
    assert rows[:, 0].tolist() == [float(k) for k in range(1, 1001)]


class _Model:
    """A native step made by a Python function called from C (ctypes): y0 = 2 u0 - u1, y1 = start [s]; it notes its
    calls' start times and fails with ``status`` at ``failing_ns``."""

    FUNCTION = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_longlong)

    def __init__(self, failing_ns: int = -1, status: int = 3, watch: ModelWatch | None = None, mark: int = -1) -> None:
        self.u, self.y = (ctypes.c_double * 2)(), (ctypes.c_double * 2)()
        self.starts: list[int] = []
        self.failing_ns, self.status = failing_ns, status
        self.function = self.FUNCTION(self._step)
        self.watch, self.marks_seen = watch, []
        self.step = NativeStep(self.function, ctypes.c_int(), self.u, self.y, lambda status: ValueError(status),
                               None if watch is None else watch.slots, mark)

    def _step(self, _argument, start_ns: int) -> int:
        self.starts.append(start_ns)
        if self.watch is not None:
            self.marks_seen.append(self.watch.slots.tolist())
        if start_ns == self.failing_ns:
            return self.status
        self.y[0], self.y[1] = 2.0 * self.u[0] - self.u[1], start_ns * 1e-9
        return 0


NATIVE_STATEMENTS = ["c = a + 1.0", "native(0)", "a = a + d * 0.5", "b = b + 1.0"]


def _native_python(values: list[float], first: int, steps: int, tick_ns: int) -> list[list[float]]:
    """What the statements above leave, in Python, the native step computed as ``_Model`` computes it."""
    a, b, c, d = values
    rows = []
    for tick in range(first, first + steps):
        c = a + 1.0
        d, e = 2.0 * c - b, tick * tick_ns * 1e-9
        a = a + d * 0.5
        b = b + 1.0
        rows.append([a, b, c, d, e])
    return rows


def test_a_native_step_is_called_with_its_inputs_and_its_steps_start_and_its_outputs_are_read():
    """``native(k)``: the inputs copied from their names' registers before the call, the call made with the start
    of the step (tick × tick_ns), the outputs copied into their names' registers after it; each step's row and the
    names left as Python leaves them, from a block that starts at tick 7."""
    model = _Model()
    program = register_loop(NAMES, NATIVE_STATEMENTS, [*NAMES, "e"], [NativeCall(model.step, ("c", "b"), ("d", "e"))],
                            tick_ns=250_000)
    values = [0.3, -1.5, 0.0, 0.0]
    program.set(NAMES, values)
    rows, _, failed = program.steps(7, 5)
    expected = _native_python(values, 7, 5, 250_000)
    assert failed is None and model.starts == [tick * 250_000 for tick in range(7, 12)]
    assert _bits(rows.ravel().tolist()) == _bits(np.ravel(expected).tolist())
    assert _bits(program.get([*NAMES, "e"])) == _bits(expected[-1])


SIGNALLING_STEP = r"""
#include <signal.h>
/* a native step that sends its own process SIGINT at the step that starts at *argument [ns] */
int step(void *argument, long long start_ns) {
    if (start_ns == *(const long long *)argument) raise(SIGINT);
    return 0;
}
"""


def test_an_interrupt_during_a_block_leaves_the_blocks_steps_to_hand_over(tmp_path):
    """A SIGINT that arrives while the program runs (sent by a native step in C at its fourth step): Python raises its
    KeyboardInterrupt as the call returns, so ``steps`` never returns the rows; ``completed`` gives those of every
    step the program ran (to the block's end: C does not see Python's signals), none for a block that did not run,
    and the next block goes on from the registers the interrupted one left."""
    compiler = c_compiler()
    if compiler is None:
        pytest.skip("no C compiler: no register program")
    source, shared = tmp_path / "signalling.c", tmp_path / "signalling.so"
    source.write_text(SIGNALLING_STEP)
    subprocess.run([compiler, *FLAGS, str(source), "-o", str(shared)], check=True)  # as subsystems.native compiles
    at_ns = ctypes.c_longlong(3 * 1000)
    step = NativeStep(ctypes.CDLL(str(shared)).step, at_ns, (ctypes.c_double * 1)(), (ctypes.c_double * 1)(),
                      ValueError)
    program = register_loop(NAMES, [STAMP_STATEMENT, "a = a + 1.0", "native(0)"], NAMES,
                            [NativeCall(step, ("a",), ("b",))], tick_ns=1000)
    program.set(NAMES, [0.0] * 4)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            program.steps(0, 10)
    finally:
        signal.signal(signal.SIGINT, previous)
    rows, times = program.completed(0)
    assert rows[:, 0].tolist() == [float(k) for k in range(1, 11)] and len(times) == 10 and (times > 0).all()
    assert len(program.completed(10)[0]) == 0
    rows, _, failed = program.steps(10, 5)
    assert failed is None and rows[:, 0].tolist() == [float(k) for k in range(11, 16)]


def test_a_native_step_that_fails_ends_the_block_at_its_step():
    """A nonzero status: the rows of the steps before it, the failing step's index and status, and the step's own
    account of its failure; the statements after the call are not run."""
    model = _Model(failing_ns=3 * 1000, status=4)
    program = register_loop(NAMES, NATIVE_STATEMENTS, [*NAMES, "e"], [NativeCall(model.step, ("c", "b"), ("d", "e"))],
                            tick_ns=1000)
    program.set(NAMES, [1.0, 2.0, 0.0, 0.0])
    rows, times, failed = program.steps(0, 10)
    expected = _native_python([1.0, 2.0, 0.0, 0.0], 0, 3, 1000)
    assert failed == Failed(0, 4) and len(rows) == len(times) == 3 and model.starts == [0, 1000, 2000, 3000]
    assert _bits(rows.ravel().tolist()) == _bits(np.ravel(expected).tolist())
    assert program.get(["a", "b"]) == expected[-1][:2]  # the failing step's statements after the call did not run
    error = program.failure(failed)
    assert isinstance(error, ValueError) and error.args == (4,)


@pytest.mark.parametrize("statements", [["native(1)"], ["native(-1)"], ["native('0')"], ["native(0, 1)"],
                                        ["native()"], [], ["native(0)", "native(0)"]],
                         ids=["no such step", "negative", "a string", "two arguments", "no argument", "never made",
                              "made twice"])
def test_a_native_call_that_names_no_native_step_gives_no_program(statements):
    assert register_loop(NAMES, statements, NAMES, [NativeCall(_Model().step, ("a",), ("b",))]) is None


def test_a_failing_native_step_is_named_by_its_index_whatever_the_order_of_the_calls():
    """Gauss–Seidel may make its subsystems' steps in another order than the plan's: the failure names the step by
    its index among the native steps given, not by its place among the statements."""
    first, second = _Model(), _Model(failing_ns=0, status=2)
    program = register_loop(NAMES, ["native(1)", "native(0)"], NAMES,
                            [NativeCall(first.step, ("a",), ("b",)), NativeCall(second.step, ("a",), ("c",))])
    assert program.steps(0, 1)[2] == Failed(1, 2) and first.starts == []


def test_a_block_ends_after_its_time_budget_and_the_next_goes_on_from_there(monkeypatch):
    """With a budget that every step exceeds, a block is one step; blocks one after the other give the rows of one
    long block."""
    monkeypatch.setattr(register_loop_module, "BUDGET_NS", -1)
    model = _Model()
    program = register_loop(NAMES, [STAMP_STATEMENT, *NATIVE_STATEMENTS], [*NAMES, "e"],
                            [NativeCall(model.step, ("c", "b"), ("d", "e"))], tick_ns=10)
    program.set(NAMES, [0.5, 0.25, 0.0, 0.0])
    blocks = [program.steps(tick, 4) for tick in range(4)]
    assert [len(rows) for rows, _, _ in blocks] == [1, 1, 1, 1] and all(failed is None for _, _, failed in blocks)
    expected = _native_python([0.5, 0.25, 0.0, 0.0], 0, 4, 10)
    assert _bits(np.concatenate([rows for rows, _, _ in blocks]).ravel().tolist()) == _bits(np.ravel(expected).tolist())


def test_in_a_watched_run_a_native_step_is_marked_as_the_watch_marks_a_call():
    """Around each call the watch's page holds what ``ModelWatch.marking`` writes for the subsystem's step from the
    step's start (the watching process names a model that hangs or ends the process from it); after the call, no
    subsystem; a call that fails leaves its mark, as a step that raises leaves it."""
    watch, expected = ModelWatch(shared=True), ModelWatch(shared=True)
    model = _Model(failing_ns=3 * 1000, watch=watch, mark=5)
    program = register_loop(NAMES, NATIVE_STATEMENTS, NAMES, [NativeCall(model.step, ("c", "b"), ("d", "e"))],
                            tick_ns=1000)
    program.set(NAMES, [1.0, 2.0, 0.0, 0.0])
    _, _, failed = program.steps(0, 2)
    seen = []
    for tick in range(2):
        with expected.marking(5, STEPPING, tick * 1000):
            seen.append(expected.slots.tolist())
    assert failed is None and model.marks_seen == seen and watch.slots.tolist() == expected.slots.tolist()
    assert watch.slots[SUBSYSTEM] == -1 and watch.slots[CALLS] == 2
    _, _, failed = program.steps(2, 3)
    assert failed == Failed(0, 3) and watch.slots[SUBSYSTEM] == 5 and watch.slots[CALLS] == 4


def test_without_a_working_compiler_there_is_no_program():
    program = ("from zencosim.manager.scheme.register_loop import register_loop; "
               "print(register_loop(['a'], ['a = a * 2.0'], ['a']))")
    result = subprocess.run([sys.executable, "-c", program], env={**os.environ, "CC": "false"}, capture_output=True,
                            text=True, check=True)
    assert result.stdout.strip() == "None"
