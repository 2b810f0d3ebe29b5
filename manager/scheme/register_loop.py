"""A generated macro-step loop run in C as a register program (``register_loop.c``; issue 26).

The loop that ``manager.scheme.compiled`` writes for a scene of small linear models is float arithmetic only: each
statement assigns a sum, difference or product of float names and constants to a name. Python runs it at about
8,600 instructions per macro-step of two_mass_damped (valgrind), most of them the interpreter's, where the
arithmetic is some sixty operations. Here each statement becomes three-address operations over one array of
doubles, the *registers* (the loop's names, its constants, the intermediate values), in Python's order of
evaluation, and ``register_loop_run`` (compiled when first needed, ``subsystems.native``) runs them step after step.
Each operation is one IEEE-754 double operation with nothing fused, as Python's float does it, so the registers hold
what the names would, bit for bit (tests/manager/test_register_loop.py).

:func:`register_loop` returns None where a statement is anything else — a call (an FMU's step), a division (which
raises in Python where C gives an infinity), an integer — or where there is no C compiler: the Python loop runs.
``stepping = …`` statements, which say which subsystem a Python exception came from, are left out: float addition,
subtraction and multiplication do not raise.

A subsystem whose step is one call of a compiled function (``subsystems.straight_line.NativeStep``: an FMU's, its
FMI calls made by ``fmi_steps.c``) is one operation, written ``native(k)`` among the statements: the program copies
its inputs from the registers, calls the function with the step's start and copies its outputs into the
registers, as the Python loop's statements do with the same values. A nonzero status ends a block of steps at that
step (:meth:`RegisterLoop.steps`). A block of a program with native steps also ends once its steps have taken
``BUDGET_NS``: a Python loop is interrupted (Ctrl-C) between two statements, a register program between two blocks
(the interrupt is raised as the block's call returns; :meth:`RegisterLoop.completed` gives the steps it ran), and a
model's step may be slow. Float arithmetic alone is fast (a block of 500 steps of a chain of 33 linear models
takes about a millisecond), and its blocks have no budget: their count of steps, and so the instructions they take,
does not depend on the machine's speed.
"""
from __future__ import annotations

import ast
import ctypes
import struct
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from zencosim.subsystems.native import library
from zencosim.subsystems.straight_line import NativeStep

ADD, SUBTRACT, MULTIPLY, NEGATE, COPY, STAMP, ADD_PRODUCT, NATIVE = range(8)  # register_loop.c's operation codes
BINARY = {ast.Add: ADD, ast.Sub: SUBTRACT, ast.Mult: MULTIPLY}
STAMP_STATEMENT = "stamp(perf())"  # the release time of the step (``time.perf_counter_ns``: CLOCK_MONOTONIC)
NATIVE_CALL = "native"  # ``native(k)``: the k-th native step (``NativeCall``)
BUDGET_NS = 100_000_000  # a block of steps with native ones ends after a step released this long after its first
NO_BUDGET_NS = (1 << 63) - 1


class Operation(ctypes.Structure):
    """``operation`` of ``register_loop.c``: ``registers[target] = registers[left] <code> registers[right]``
    (``ADD_PRODUCT``: ``registers[left] + registers[right] * registers[factor]``)."""

    _fields_ = [("code", ctypes.c_int), ("target", ctypes.c_int), ("left", ctypes.c_int), ("right", ctypes.c_int),
                ("factor", ctypes.c_int)]


class NativeStepC(ctypes.Structure):
    """``native_step`` of ``register_loop.c``."""

    _fields_ = [("run", ctypes.c_void_p), ("argument", ctypes.c_void_p), ("u", ctypes.c_void_p),
                ("inputs", ctypes.c_void_p), ("n_inputs", ctypes.c_longlong), ("y", ctypes.c_void_p),
                ("outputs", ctypes.c_void_p), ("n_outputs", ctypes.c_longlong), ("marks", ctypes.c_void_p),
                ("mark", ctypes.c_longlong)]


class NativeCall(NamedTuple):
    """A native step of a macro-step: the step, the names its inputs are read from and its outputs written to."""

    step: NativeStep
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]


class Failed(NamedTuple):
    """A native step that failed: its index among the program's ``NativeCall`` and the status it returned."""

    native: int
    status: int


class NotArithmetic(Exception):
    """A statement the register program cannot run as Python would."""


class RegisterLoop:
    """A macro-step's statements as a register program: set the names, run steps, read the names."""

    def __init__(self, run, operations: list[tuple[int, int, int, int, int]], registers: list[float],
                 names: dict[str, int], row: list[int], natives: list[tuple[NativeStep, list[int], list[int]]],
                 tick_ns: int) -> None:
        self._run = run
        self._operations = (Operation * len(operations))(*operations)
        self.registers = np.array(registers, dtype=np.float64)
        self.names = names
        self._row = np.array(row, dtype=np.intc)
        self._indices = [(np.array(inputs, dtype=np.intc), np.array(outputs, dtype=np.intc))
                         for _, inputs, outputs in natives]  # kept: the C structs point into them
        self._steps = [step for step, _, _ in natives]
        self._natives = (NativeStepC * max(len(natives), 1))(*(
            NativeStepC(ctypes.cast(step.function, ctypes.c_void_p).value, ctypes.addressof(step.argument),
                        ctypes.addressof(step.u), inputs.ctypes.data, len(inputs), ctypes.addressof(step.y),
                        outputs.ctypes.data, len(outputs), _address(step.marks), step.mark)
            for step, (inputs, outputs) in zip(self._steps, self._indices)))
        self._tick_ns = tick_ns
        # the native step that failed and its status (0: none failed), the steps of the last run and its first tick
        self._outcome = (ctypes.c_longlong * 4)(0, 0, 0, -1)
        self._block = (np.empty((0, len(self._row))), np.zeros(0, dtype=np.int64))  # the last run's rows and times

    def set(self, names: Iterable[str], values: Iterable[float]) -> None:
        for name, value in zip(names, values, strict=True):
            self.registers[self.names[name]] = value

    def get(self, names: Iterable[str]) -> list[float]:
        return self.registers[[self.names[name] for name in names]].tolist()

    def steps(self, first: int, count: int) -> tuple[np.ndarray, np.ndarray, Failed | None]:
        """Run up to ``count`` macro-steps from tick ``first``: the rows (a row per step) and release times [ns] of
        those that completed — all of them, those within ``BUDGET_NS`` (where there are native steps), or those
        before a native step failed (:class:`Failed`, else None)."""
        self._block = rows, times = np.empty((count, len(self._row))), np.zeros(count, dtype=np.int64)
        done = self._run(self._operations, len(self._operations), self.registers.ctypes.data, self._row.ctypes.data,
                         len(self._row), count, rows.ctypes.data, times.ctypes.data, self._natives, first,
                         self._tick_ns, BUDGET_NS if self._steps else NO_BUDGET_NS, self._outcome)
        failed = None
        if self._outcome[1]:
            failed, self._outcome[1] = Failed(self._outcome[0], self._outcome[1]), 0
        return rows[:done], times[:done], failed

    def completed(self, first: int) -> tuple[np.ndarray, np.ndarray]:
        """The rows and release times of the steps that the run of :meth:`steps` from tick ``first`` completed (none
        where it did not run): what it returns, for a run that an interrupt cut short as it returned. Python raises
        the KeyboardInterrupt of a SIGINT that arrived during the C call as the call returns, before ``steps`` has
        the number of steps that it ran."""
        done = self._outcome[2] if self._outcome[3] == first else 0
        rows, times = self._block
        return rows[:done], times[:done]

    def failure(self, failed: Failed) -> BaseException:
        """What the native step that failed says of its failure."""
        return self._steps[failed.native].failure(failed.status)


def _address(buffer) -> int | None:
    """The address of a writable buffer (a watch's page: ``NativeStep.marks``), None for None."""
    return None if buffer is None else ctypes.addressof(ctypes.c_char.from_buffer(buffer))


def register_loop(initial: list[str], statements: list[str], row: list[str], natives: list[NativeCall] = (),
                  tick_ns: int = 0) -> RegisterLoop | None:
    """The register program of a macro-step: the names ``initial`` hold values before the first step, one step is
    ``statements`` (``manager.scheme.compiled``'s loop body), its row the names ``row``; ``native(k)`` among them is
    ``natives[k]``, called with the start of its step (tick × ``tick_ns``). None where a statement is not float
    arithmetic or there is no C compiler (see the module text)."""
    try:
        translation = _Translation(initial, natives)
        for statement in statements:
            translation.statement(statement)
        row_registers = [translation.read(name) for name in row]
        natives_made = [translation.natives[k] for k in range(len(natives))]
    except (NotArithmetic, KeyError):  # KeyError: a native step that no statement makes
        return None
    compiled = library("zencosim.manager.scheme", "register_loop.c")
    if compiled is None:
        return None
    run = compiled.register_loop_run
    run.restype = ctypes.c_longlong
    run.argtypes = [ctypes.POINTER(Operation), ctypes.c_longlong, ctypes.c_void_p, ctypes.c_void_p,
                    ctypes.c_longlong, ctypes.c_longlong, ctypes.c_void_p, ctypes.c_void_p,
                    ctypes.POINTER(NativeStepC), ctypes.c_longlong, ctypes.c_longlong, ctypes.c_longlong,
                    ctypes.POINTER(ctypes.c_longlong)]
    return RegisterLoop(run, translation.operations, translation.registers, translation.names, row_registers,
                        natives_made, tick_ns)


class _Translation:
    """Statements to operations: a name's register is assigned at its first assignment, a constant's at its first
    use (one per value, -0.0 apart from 0.0), an intermediate value's where it is computed."""

    def __init__(self, initial: list[str], natives: list[NativeCall]) -> None:
        self.names = {name: i for i, name in enumerate(initial)}
        self.registers = [0.0] * len(initial)
        self.constants: dict[bytes, int] = {}
        self.operations: list[tuple[int, int, int, int, int]] = []
        self.calls = natives
        self.natives: dict[int, tuple[NativeStep, list[int], list[int]]] = {}  # by index: its input, output registers

    def statement(self, text: str) -> None:
        if text == STAMP_STATEMENT:
            self.operations.append((STAMP, 0, 0, 0, 0))
            return
        (node,) = ast.parse(text).body
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Call) \
                and isinstance(node.value.func, ast.Name) and node.value.func.id == NATIVE_CALL:
            self._native(node.value)
            return
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)):
            raise NotArithmetic(text)
        name = node.targets[0].id
        if name == "stepping":
            return
        target = self.names.get(name)
        if target is None:
            target = self._new(0.0)
        if isinstance(node.value, (ast.BinOp, ast.UnaryOp)) and _constant(node.value) is None:
            self._value(node.value, target)  # its last operation writes the name, after its operands were read
        else:
            self.operations.append((COPY, target, self._value(node.value), 0, 0))
        self.names[name] = target

    def _native(self, call: ast.Call) -> None:
        """``native(k)``: the k-th native step, its inputs read from their names' registers, its outputs written to
        theirs."""
        index = call.args[0].value if len(call.args) == 1 and isinstance(call.args[0], ast.Constant) else None
        if type(index) is not int or not 0 <= index < len(self.calls) or index in self.natives:
            raise NotArithmetic(ast.unparse(call))  # no such step, or one made twice a step
        step, inputs, outputs = self.calls[index]
        input_registers = [self.read(name) for name in inputs]
        output_registers = []
        for name in outputs:
            if name not in self.names:
                self.names[name] = self._new(0.0)
            output_registers.append(self.names[name])
        self.operations.append((NATIVE, 0, index, 0, 0))
        self.natives[index] = (step, input_registers, output_registers)

    def read(self, name: str) -> int:
        if name not in self.names:  # read before any assignment: a NameError in Python
            raise NotArithmetic(name)
        return self.names[name]

    def _value(self, node: ast.expr, target: int | None = None) -> int:
        """The register that holds ``node``'s value, computed into ``target`` where it is an operation."""
        value = _constant(node)
        if value is not None:
            key = struct.pack("<d", value)
            if key not in self.constants:
                self.constants[key] = self._new(value)
            return self.constants[key]
        if isinstance(node, ast.Name):
            return self.read(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            operand = self._value(node.operand)
            target = self._new(0.0) if target is None else target
            self.operations.append((NEGATE, target, operand, 0, 0))
            return target
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add) and isinstance(node.right, ast.BinOp) \
                and isinstance(node.right.op, ast.Mult):  # a + b * c, a linear combination's next term: one operation
            left, right, factor = self._value(node.left), self._value(node.right.left), self._value(node.right.right)
            target = self._new(0.0) if target is None else target
            self.operations.append((ADD_PRODUCT, target, left, right, factor))
            return target
        if isinstance(node, ast.BinOp) and type(node.op) in BINARY:
            left, right = self._value(node.left), self._value(node.right)
            target = self._new(0.0) if target is None else target
            self.operations.append((BINARY[type(node.op)], target, left, right, 0))
            return target
        raise NotArithmetic(ast.unparse(node))

    def _new(self, value: float) -> int:
        self.registers.append(value)
        return len(self.registers) - 1


def _constant(node: ast.expr) -> float | None:
    """A float literal's value, or a negated one's (Python folds ``-0.11`` into a constant); else None."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        value = _constant(node.operand)
        return None if value is None else -value
    if isinstance(node, ast.Constant) and type(node.value) is float:
        return node.value
    return None
