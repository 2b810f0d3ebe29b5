"""The contract between a scheme and the buses that drive it (``manager.scheme.replica``).

A scheme (``jacobi``, ``implicit``) is a generator: it yields :class:`Exchange` requests — the
encoded commands to send and the subsystems whose replies it needs next — is sent the replies, and
returns a :class:`RunRecord`. Replies are read with :func:`decode_output` / :func:`expect_reply`,
which name the subsystem in every error.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.window import RowWindow, Spill, read_rows
from zencosim.manager.wire.protocol import HEADER, VERSION, Kind, ProtocolError, decode, decode_header
from zencosim.subsystems.straight_line import StepText

PROGRESS_EVERY = 500  # base steps between two progress callbacks
HISTORY_ROWS = 8  # rows of a trajectory a scheme reads back: Lagrange samples (order + 1 <= 3), correctors (2)


class SubsystemFailure(RuntimeError):
    """A subsystem answered with an error, died, or did not answer in time."""

    def __init__(self, subsystem: str, reason: str) -> None:
        self.subsystem = subsystem
        super().__init__(f"subsystem {subsystem}: {reason}")


@dataclass(slots=True)
class Exchange:
    """Send ``sends`` (subsystem name → message) and hand back the replies of ``awaits``; ``status``, when
    the run reports it, is the macro-step that has just ended, whose STATUS message is the next in the log of the
    run's ``StatusReport`` (``manager.wire.status``: ``take`` it); ``step``, when given, the step of the replies
    awaited (``manager.scheme.replica`` checks it for replies from the network).

    ``shape``, when given, stands for the names the exchange goes through: two requests of a run with the same
    shape follow requests that awaited the same subsystems (the replies handed back with them), both report a
    status or neither, send to the same subsystems in the same order and await the same ones. A tap derives what
    it needs of the names once per shape (``recordings.recorder``) instead of once per exchange.

    A class with slots, not a NamedTuple: Python 3.11 reads a slot with a specialised instruction and a
    NamedTuple's field through the generic attribute lookup, and the stepping loop reads three or four fields of
    every request (the replica, the recorder's tap)."""

    sends: dict[str, bytes]
    awaits: tuple[str, ...]
    status: int | None = None
    step: int | None = None  # the step every awaited OUTPUT or ACK carries (a reply from the network is checked)
    shape: int | None = None


class Corrector(Protocol):
    """What the manager adds to inputs each step (DESIGN: energy correction, compensator terms)."""

    targets: frozenset[int]  # subsystems whose input polynomials it adjusts

    def adjust(self, sub: int, tick: int, coefficients: np.ndarray) -> np.ndarray:
        """The polynomial subsystem ``sub`` receives at base step ``tick`` (a copy; the argument is kept)."""

    def observe(self, tick: int, trajectories: list[RowWindow], residual_energy: RowWindow) -> None:
        """Outputs due at ``tick`` are committed and the residuals of the bonds due there evaluated (the newest
        rows of each, ``RowWindow.row``)."""

    def log(self) -> tuple:
        """What the corrector did, for the run record (one entry per corrected point)."""


@dataclass
class ImplicitRecord:
    """What the implicit scheme adds to a :class:`RunRecord`."""

    coupling_variables: np.ndarray  # (n_ticks + 1, n_e) e_N, variable-major (RigidJoint.coupling_variables)
    corrector_runs: np.ndarray  # (n_ticks,) corrector runs in each macro-step (0 after a divergence)
    diverged_at: int | None  # macro-step at whose end the joint opened wider than divergence_gap (or not finite)


class SubsystemCalls(Protocol):
    """The subsystems of an in-process run, called by the scheme itself (``manager.bus.inproc.DirectCalls``)."""

    def initial(self, s: SubsystemPlan, w0: np.ndarray) -> np.ndarray:
        """``s``'s outputs at t_0 with the input values ``w0`` (an INIT command's)."""

    def step(self, s: SubsystemPlan, tick: int, coefficients: np.ndarray | list[float], span: int = 0
             ) -> list[float] | np.ndarray:
        """``s``'s outputs at the end of its step from base step ``tick`` over the input polynomial ``coefficients``
        (a STEP command's), both as ``Subsystem.advance_values`` takes and gives them; ``span``: the step's length in
        base steps (0: its communication step; as a STEP's header field)."""

    def step_text(self, s: SubsystemPlan, prefix: str, start_ns: str) -> StepText | None:
        """``s``'s zero-order step as statements over names prefixed ``prefix``, its start [ns] the expression
        ``start_ns`` (``Subsystem.step_text``: for a loop that runs it itself, ``manager.scheme.compiled``), or None."""

    def failure(self, s: SubsystemPlan, due: int, error: BaseException) -> BaseException:
        """What ``s`` raising ``error`` in its step to ``due`` ends the run with (a model's failure, named as its
        ERROR reply would name it, or the user's interrupt as it was)."""

    def state(self, s: SubsystemPlan) -> list[float]:
        """``s``'s state now, as the statements of ``step_text`` read it."""

    def took_steps(self, s: SubsystemPlan, tick: int, z: list[float], w: list[float]) -> None:
        """``s`` is at base step ``tick`` with the state ``z`` and input values ``w`` that a loop running its
        statements left (``Subsystem.took_steps``)."""


@dataclass
class RunRecord:
    """What one run produced, on the base macro-step grid (an energy-controlled run: at its ``point_ticks``)."""

    plan: Plan
    trajectories: list[np.ndarray]  # per subsystem: outputs at its communication points (a long run's: mapped files,
    # read them to the end with manager.scheme.window.row_blocks)
    residual_power: np.ndarray  # (n_ticks + 1, n_bonds) [W], NaN where a bond was not evaluated
    residual_energy: np.ndarray  # (n_ticks + 1, n_bonds) [J], cumulative
    send_time_ns: np.ndarray  # (macro-steps executed,) wall clock (perf_counter_ns) when step j's inputs went out
    lateness_ns: np.ndarray | None  # (macro-steps executed,) real-time mode: send time minus deadline
    missed_deadlines: int
    corrections: tuple = ()  # the correctors' logs (manager.scheme.correction.CorrectionLog), one per corrected point
    implicit: ImplicitRecord | None = None  # what the implicit scheme adds (manager.scheme.implicit)
    reported_timing: dict[str, dict] | None = None  # over Zenoh: each subsystem's step timing (manager.bus.timing)
    manager_cpu_s: float | None = None  # over Zenoh: the manager's CPU time [s] while the run stepped
    dropped_messages: dict[str, dict] | None = None  # over Zenoh: messages dropped per key (manager.bus.dropped.merge)
    # an energy-controlled run (manager.scheme.energy_step): the base step of each of its points, which are the rows of
    # the residual arrays (a subsystem's trajectory: every ratio-th point); None: a point per base step
    point_ticks: np.ndarray | None = None

    @property
    def last_step(self) -> int:
        """The last base macro-step whose outputs were committed: ``plan.n_ticks`` unless an implicit run
        diverged (then its last step only if it got as far as the corrector)."""
        if self.implicit is None or self.implicit.diverged_at is None:
            return self.plan.n_ticks
        diverged = self.implicit.diverged_at
        return diverged + 1 if self.implicit.corrector_runs[diverged] > 0 else diverged

    def row_count(self, every: int = 1) -> int:
        """The rows of an array sampled every ``every`` base steps (a subsystem's trajectory: its ratio; the residuals:
        1) — of an energy-controlled run, every ``every`` points."""
        points = self.plan.n_ticks if self.point_ticks is None else len(self.point_ticks) - 1
        return points // every + 1

    def row_ticks(self, first: int, stop: int, every: int = 1) -> np.ndarray:
        """The base steps of rows ``first … stop - 1`` of such an array (``row_count``)."""
        return grid_ticks(self.point_ticks, every, first, stop)

    def signal(self, name: str) -> np.ndarray:
        """The trajectory of output ``name`` at its subsystem's communication points."""
        sub_index, output = self.plan.signals[name]
        return self.trajectories[sub_index][:, output]


def grid_ticks(point_ticks: np.ndarray | None, every: int, first: int, stop: int) -> np.ndarray:
    """The base steps of rows ``first … stop - 1`` of an array sampled every ``every`` base steps — of an
    energy-controlled run (``RunRecord.point_ticks``), every ``every`` of its points (read as ``read_rows`` reads)."""
    if point_ticks is not None:
        return read_rows(point_ticks[::every], first, stop)
    return np.arange(first, stop, dtype=np.int64) * every


def decode_output(data: bytes, sub: SubsystemPlan, step: int) -> np.ndarray:
    """The outputs a reply of ``sub`` carries for ``step``; anything else is a named error."""
    check_output(data, sub, step)
    return np.frombuffer(data, dtype="<f8", count=len(sub.outputs), offset=HEADER.size)


def check_output(data: bytes, sub: SubsystemPlan, step: int) -> None:
    """Raise a named error unless ``data`` is the reply of ``sub`` with its outputs for ``step``."""
    n = len(sub.outputs)
    if len(data) == HEADER.size + 8 * n:  # the expected reply: one header check
        version, kind, _, count, reply_step, _, _ = HEADER.unpack_from(data)
        if version == VERSION and kind == Kind.OUTPUT and reply_step == step and count == n:
            return
    message = expect_reply(data, sub, Kind.OUTPUT, step)
    raise ProtocolError(f"subsystem {sub.name}: expected {n} outputs, got {message.values.size}")


class OutputReader:
    """The committed outputs of one subsystem: its trajectory at its communication points, filled as its replies
    arrive (their values copied as they are, bytes) into a window of its newest rows (``manager.scheme.window``),
    and the newest reply with its values as floats."""

    def __init__(self, sub: SubsystemPlan, points: int, spill: Spill | None = None) -> None:
        self.sub = sub
        self.window = RowWindow(points, len(sub.outputs), "<f8", np.nan, HISTORY_ROWS, spill, f"{sub.name}-outputs")
        self._bytes = memoryview(self.window.array.view(np.uint8).reshape(-1))  # also for no rows (an untracked source)
        self._width = 8 * len(sub.outputs)
        self._unpack = struct.Struct(f"<{len(sub.outputs)}d").unpack_from
        self.newest: Sequence[float] = ()  # the values of the newest reply
        self.newest_bytes = b""  # the newest reply, header and values

    def commit(self, data: bytes, step: int, row: int | None = None) -> None:
        """Take ``sub``'s reply for ``step`` (a named error when it is not one) into row ``row`` of its trajectory
        (None: the row of ``step`` on its communication grid; a run whose points are not evenly spaced names it:
        ``manager.scheme.energy_step``)."""
        check_output(data, self.sub, step)
        if row is None:
            row = step // self.sub.ratio
        window = self.window
        if row >= window.end:
            window.advance(row)
        start = (row - window.offset) * self._width
        self._bytes[start:start + self._width] = memoryview(data)[HEADER.size:]
        self.newest = self._unpack(data, HEADER.size)
        self.newest_bytes = data

    def commit_values(self, y: list[float] | np.ndarray, step: int, row: int | None = None) -> None:
        """Take ``sub``'s outputs for ``step`` as this process computed them (the scheme calling the subsystem
        itself: ``manager.bus.inproc.DirectCalls``; floats or an array): the values ``commit`` takes from their
        reply, without the bytes, into row ``row`` as ``commit`` takes it."""
        if type(y) is not list:
            if y.shape != self.window.row_shape:
                raise ProtocolError(f"subsystem {self.sub.name}: expected {len(self.sub.outputs)} outputs, got {y.size}")
            y = y.tolist()
        elif len(y) != len(self.sub.outputs):  # a straight-line step's: always its model's outputs
            raise ProtocolError(f"subsystem {self.sub.name}: expected {len(self.sub.outputs)} outputs, got {len(y)}")
        if row is None:
            row = step // self.sub.ratio
        window = self.window
        if row >= window.end:
            window.advance(row)
        window.array[row - window.offset] = y
        self.newest = y


REPLY_KINDS = (Kind.OUTPUT, Kind.ACK, Kind.ERROR)


def reply_fault(reply: bytes, sender: str, expected_ref: int | None, step: int | None) -> str | None:
    """Why a replica must not take ``reply``, the next of subsystem ``sender`` from the network (None: it may): a
    malformed header, a message that is no reply, a reply to another command than the one this replica computed
    (``expected_ref``: its reference; None: this replica did not compute it), else one for another step than
    ``step``, the step awaited (an ERROR is taken whatever its step: it ends the run)."""
    try:
        kind, _, _, reply_step, _, ref = decode_header(reply, f"subsystem {sender}")
    except ProtocolError as error:
        return str(error)
    if kind not in REPLY_KINDS:
        return f"a {kind.name} message, which is no reply"
    if expected_ref is not None:
        if ref != expected_ref:
            return (f"answers another command than this replica computed (reference {ref} instead of "
                    f"{expected_ref}): another process publishes here, or the subsystem's copy of the scheme "
                    "diverged (run every process with the same zencosim, numpy and scene)")
    elif step is not None and reply_step != step and kind != Kind.ERROR:
        return f"a {kind.name} for step {reply_step}; the scheme awaits step {step}"
    return None


def expect_reply(data: bytes, sub: SubsystemPlan, expected: Kind, step: int, command: Kind | None = None):
    """The reply of ``sub`` for ``step``, which must be of kind ``expected`` (answering ``command``):
    an ERROR is the subsystem's failure, anything else a protocol error; both name the subsystem."""
    message = decode(data, f"subsystem {sub.name}")
    if message.kind == Kind.ERROR:
        doing = "failed" if command is None else f"cannot {command.name.lower()}"
        raise SubsystemFailure(sub.name, f"{doing} at step {step}: {message.text()}")
    if message.kind != expected or message.step != step:
        awaited = expected.name if command is None else f"{expected.name} to {command.name}"
        raise ProtocolError(f"subsystem {sub.name}: expected {awaited} for step {step}, "
                            f"got {message.kind.name} for step {message.step}")
    return message
