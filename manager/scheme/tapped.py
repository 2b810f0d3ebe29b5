"""What the tap of a direct run sees (``manager.scheme.jacobi`` calling its subsystems itself: an in-process run).

A replica hands its tap each request with the replies the scheme took to make it (``manager.scheme.replica``). A
direct run has no replica and no messages; for a recorded one, the scheme hands the tap what a replica would have:
the commands it computed and the replies its subsystems would have sent, in that order.

:class:`Taken` encodes them exchange by exchange, for any tap and for a paced (real-time) run, whose live view
follows it step by step. :class:`TakenSteps`, for a tap that takes blocks of arrays (the recorder's ``take_steps``),
keeps the stepping loop's arrays and hands over a :class:`StepsBlock` about every ``BLOCK_STEPS`` requests: each
subsystem's commands (ticks and input polynomials) and replies (steps, outputs), and the order of the exchanges; the
recorder process builds the wire messages and each reply's reference, the CRC-32 of its command
(``recordings.steps_frame``). Encoding and handing over every message on the stepping loop cost the recorded
in-process loop of two_mass_damped a third more instructions per step (benchmarks/bench_instructions.py
--recording).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.base import Exchange
from zencosim.manager.scheme.replica import Tap
from zencosim.manager.wire.protocol import Kind, command_ref, encode

BLOCK_STEPS = 256  # requests of the stepping loop handed over at once (TakenSteps)
LONGEST_PERIOD = 16 * BLOCK_STEPS  # base steps: a longer schedule period is tapped exchange by exchange


def taken_for(tap, plan: Plan, paced: bool) -> Taken | TakenSteps:
    """What hands a direct run's messages to ``tap``: blocks of arrays where the tap takes them (``take_steps``), the
    run is not paced (a real-time run's live view follows it step by step) and a block, which holds whole schedule
    periods, stays small (the lcm of the communication ratios at most ``LONGEST_PERIOD`` base steps); else
    exchange by exchange."""
    if not paced and hasattr(tap, "take_steps") and math.lcm(*(s.ratio for s in plan.subsystems)) <= LONGEST_PERIOD:
        return TakenSteps(tap, plan)
    return Taken(tap, plan)


class Taken:
    """Hands ``tap`` each request of a direct run as it is made, with the replies taken to make it (None before the
    first), then the replies of the last with None."""

    def __init__(self, tap: Tap, plan: Plan) -> None:
        self.tap = tap
        self.base_step_ns = plan.base_step_ns
        self.replies: dict[int, bytes] = {}  # per subsystem: its reply to its last command
        self.sends: dict[str, bytes] = {}  # the last request's commands
        self.due: tuple[SubsystemPlan, ...] | None = None  # whose replies the last request of the stepping loop awaits
        self.last: dict[str, bytes] | None = None  # the replies the next request follows

    def initial(self, request: Exchange, outputs: dict[SubsystemPlan, np.ndarray]) -> None:
        """An initialisation round: its request, and the outputs its subsystems answered (the next request follows
        their replies)."""
        self.tap.exchange(self.last, request)
        self.last = {s.name: encode(Kind.OUTPUT, 0, 0, y, ref=command_ref(request.sends[s.name]))
                     for s, y in outputs.items()}

    def request(self, starting: list[tuple[SubsystemPlan, np.ndarray | list[float]]], awaits: tuple[str, ...],
                status: int | None, step: int, shape: int | None, due: tuple[SubsystemPlan, ...], tick: int) -> None:
        """A request of the stepping loop: STEP commands with the input polynomials of ``starting`` at ``tick``,
        awaiting ``due`` (``awaits``: their names), whose replies carry ``step``."""
        self._took()
        self.sends = {s.name: encode(Kind.STEP, tick, tick * self.base_step_ns, np.asarray(coefficients, dtype=float),
                                     s.order + 1)
                      for s, coefficients in starting}
        self.tap.exchange(self.last, Exchange(self.sends, awaits, status, step, shape))
        self.due = due

    def reply(self, s: SubsystemPlan, step: int, outputs: list[float] | np.ndarray) -> None:
        """``s``'s outputs for ``step``, computed by its step from its command in the last request."""
        self.replies[s.index] = encode(Kind.OUTPUT, step, step * self.base_step_ns, np.asarray(outputs, dtype=float),
                                       ref=command_ref(self.sends[s.name]))

    def end(self, status: int | None) -> None:
        """The run has ended: the last status, then the replies of the last request with None."""
        self._took()
        if status is not None:
            self.tap.exchange(self.last, Exchange({}, (), status))
            self.last = {}
        self.tap.exchange(self.last, None)

    def failed(self) -> None:
        """The run ended in the last request: the tap has seen it, as a replica's would."""

    def _took(self) -> None:
        """The scheme took the replies the last request of the stepping loop awaited."""
        if self.due is not None:
            self.last = {s.name: self.replies[s.index] for s in self.due}


@dataclass
class SubsystemSteps:
    """One subsystem's messages in a :class:`StepsBlock`: its STEP commands and its OUTPUT replies, in order; the
    k-th reply answers the k-th command (its reference is that command's CRC-32)."""

    ticks: np.ndarray  # int64: each command's step (and time: times the base step)
    polynomials: np.ndarray  # (commands, rows × inputs): each command's values
    rows: int  # of each polynomial
    steps: np.ndarray  # int64: each reply's step
    outputs: np.ndarray  # (replies, outputs)


@dataclass
class StepsBlock:
    """Exchanges of a direct run: ``layouts[i]`` is (the subsystems whose replies come first, whether the status
    follows, the subsystems commanded), ``order`` the layout of each exchange in turn; each subsystem's messages in
    ``subsystems`` (by plan index, ``names``) are taken in order as the exchanges name them. A block answers its own
    commands: it holds whole schedule periods and ends with the replies of its last exchange (then the next block
    starts without replies), so that it can be encoded on its own."""

    names: tuple[str, ...]
    base_step_ns: int  # a message's time is its step times this
    layouts: list[tuple[tuple[int, ...], bool, tuple[int, ...]]]
    order: np.ndarray  # uint32
    subsystems: list[SubsystemSteps]
    statuses: int  # exchanges that report a status (the statuses are the next in the run's status log)
    last: bool  # the run's last block


class TakenSteps:
    """What :class:`Taken` hands its tap, as a :class:`StepsBlock` to ``tap.take_steps`` at the first schedule period
    that starts after ``BLOCK_STEPS`` requests, when the run ends and when it fails. The initialisation's rounds go
    to ``tap.exchange`` as :class:`Taken` hands them, and so do the replies of its last round, with a request that
    sends nothing (a replica hands them with the first request of the stepping loop: the same messages, in the same
    order)."""

    def __init__(self, tap, plan: Plan) -> None:
        self.tap = tap
        self.plan = plan
        n = len(plan.subsystems)
        self.names = tuple(s.name for s in plan.subsystems)
        self.layout_of: dict[tuple, int] = {}  # layout → its number in every block
        self.layout_of_shape: dict[int, int] = {}  # a request's shape → its layout's number (not a block's first)
        self.order: list[int] = []  # the block's exchanges, by layout
        self.statuses = 0  # the block's exchanges that report a status
        # per subsystem: the block's commands (ticks, polynomials) and replies (steps, outputs)
        self.ticks: list[list[int]] = [[] for _ in range(n)]
        self.polynomials: list[list[np.ndarray | list[float]]] = [[] for _ in range(n)]
        self.steps: list[list[int]] = [[] for _ in range(n)]
        self.outputs: list[list[list[float] | np.ndarray]] = [[] for _ in range(n)]
        self.due: tuple[SubsystemPlan, ...] = ()  # whose replies the next exchange starts with
        self.initial_replies = Taken(tap, plan)  # the initialisation, exchange by exchange

    def initial(self, request: Exchange, outputs: dict[SubsystemPlan, np.ndarray]) -> None:
        """As :meth:`Taken.initial`."""
        self.initial_replies.initial(request, outputs)

    def request(self, starting: list[tuple[SubsystemPlan, np.ndarray | list[float]]], awaits: tuple[str, ...],
                status: int | None, step: int, shape: int | None, due: tuple[SubsystemPlan, ...], tick: int) -> None:
        """As :meth:`Taken.request`; the polynomials are kept (not copied: the scheme makes new ones every step)."""
        if self.initial_replies is not None:  # the initialisation's last replies, before the stepping loop
            if self.initial_replies.last:
                self.tap.exchange(self.initial_replies.last, Exchange({}, ()))
            self.initial_replies = None
        elif shape == 0 and len(self.order) >= BLOCK_STEPS:  # a schedule period starts: every command is answered
            self.flush()
        if not self.order:  # a block's first exchange: the replies before it ended the block before
            layout = self._layout((), status is not None, tuple(s for s, _ in starting))
        else:
            layout = self.layout_of_shape.get(shape)
            if layout is None:
                layout = self.layout_of_shape[shape] = self._layout(self.due, status is not None,
                                                                    tuple(s for s, _ in starting))
        self.order.append(layout)
        self.statuses += status is not None
        ticks, polynomials = self.ticks, self.polynomials
        for s, coefficients in starting:
            ticks[s.index].append(tick)
            polynomials[s.index].append(coefficients)
        self.due = due

    def reply(self, s: SubsystemPlan, step: int, outputs: list[float] | np.ndarray) -> None:
        """As :meth:`Taken.reply` (a copy: a model may reuse its array)."""
        self.steps[s.index].append(step)
        self.outputs[s.index].append(outputs.copy())

    def end(self, status: int | None) -> None:
        """The run has ended: the last status, then the replies of the last request."""
        if status is not None:
            self.order.append(self._layout(self.due, True, ()))
            self.statuses += 1
            self.due = ()
        self.flush(last=True)

    def failed(self) -> None:
        """The run ended in the last request: the block up to its commands (the replies it awaits never came)."""
        self.due = ()
        self.flush()

    def flush(self, last: bool = False) -> None:
        """Hand the block over, ended by the replies of its last exchange (nothing when it holds no exchange);
        ``last``: the run's last. The block holds the replies its exchanges hand over (not those of a last request
        that the scheme never took: a run that failed or was interrupted), and it is built before anything is
        cleared, so that an interrupt while it is built leaves it whole for ``failed``."""
        if self.due:
            self.order.append(self._layout(self.due, False, ()))
            self.due = ()
        if not self.order:
            return
        layouts = list(self.layout_of)
        handed = [0] * len(self.names)  # replies each subsystem hands over in the block
        for (replying, _, _), uses in zip(layouts, np.bincount(self.order, minlength=len(layouts)).tolist()):
            for i in replying:
                handed[i] += uses
        subsystems = []
        for s in self.plan.subsystems:
            i, width, k = s.index, (s.order + 1) * len(s.inputs), handed[s.index]
            ticks, polynomials = self.ticks[i], self.polynomials[i]
            subsystems.append(SubsystemSteps(
                np.array(ticks, dtype=np.int64),
                np.concatenate(polynomials).reshape(len(ticks), width) if ticks else np.zeros((0, width)), s.order + 1,
                np.array(self.steps[i][:k], dtype=np.int64),
                np.concatenate(self.outputs[i][:k]).reshape(k, len(s.outputs)) if k else np.zeros((0, len(s.outputs)))))
        block = StepsBlock(self.names, self.plan.base_step_ns, layouts, np.array(self.order, dtype=np.uint32),
                           subsystems, self.statuses, last)
        for kept in (self.ticks, self.polynomials, self.steps, self.outputs):
            for each in kept:
                each.clear()
        self.order, self.statuses = [], 0
        self.tap.take_steps(block)

    def _layout(self, replying: tuple[SubsystemPlan, ...], status: bool, commanded: tuple[SubsystemPlan, ...]) -> int:
        """The number of the layout (subsystems replying, status, subsystems commanded), by plan index."""
        key = (tuple(s.index for s in replying), status, tuple(s.index for s in commanded))
        return self.layout_of.setdefault(key, len(self.layout_of))
