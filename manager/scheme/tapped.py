"""What the tap of a direct run sees (``manager.scheme.jacobi`` calling its subsystems itself: an in-process run).

A replica hands its tap each request with the replies the scheme took to make it (``manager.scheme.replica``). A
direct run has no replica and no messages; for a recorded one, the scheme hands the tap what a replica would have:
the commands it computed and the replies its subsystems would have sent, in that order.

:class:`Taken` encodes them exchange by exchange, for any tap and for a paced (real-time) run, whose live view
follows it step by step. :class:`TakenSteps`, for a tap that takes blocks of arrays (the recorder's ``take_steps``),
keeps the values the stepping loop appends to its lists and hands over a :class:`StepsBlock` about every
``BLOCK_STEPS`` requests: each subsystem's commands (ticks and input polynomials) and replies (steps, outputs), and
the order of the exchanges; the recorder process builds the wire messages and each reply's reference, the CRC-32 of
its command (``recordings.steps_frame``). Encoding and handing over every message on the stepping loop cost the
recorded in-process loop of two_mass_damped a third more instructions per step (stop 29; the blocks' cost:
docs/recording.md, benchmarks/bench_instructions.py --recording).
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


def taken_for(tap, plan: Plan, paced: bool, status: bool, stages: list[tuple]) -> Taken | TakenSteps:
    """What hands a direct run's messages to ``tap``: blocks of arrays where the tap takes them (``take_steps``), the
    run is not paced (a real-time run's live view follows it step by step) and a block, which holds whole schedule
    periods, stays small (the lcm of the communication ratios at most ``LONGEST_PERIOD`` base steps); else
    exchange by exchange. ``status``: the run reports its status; ``stages``: its schedule's phases
    (``manager.scheme.jacobi.schedule``)."""
    if not paced and hasattr(tap, "take_steps") and math.lcm(*(s.ratio for s in plan.subsystems)) <= LONGEST_PERIOD:
        return TakenSteps(tap, plan, status, stages)
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
    sends nothing (``start``; a replica hands them with the first request of the stepping loop: the same messages,
    in the same order).

    The stepping loop calls nothing here per step: it appends to flat lists of numbers (``manager.scheme.jacobi``) —
    each request's tick and shape to ``ticks`` and ``shapes`` (after its commands), each command's polynomial
    (its values, rows after rows) to ``commands`` and each reply's outputs to ``outputs`` of its subsystem — and
    calls ``flush`` where a period starts after a full block. Flat lists of floats, not a list per message: the
    cyclic garbage collector walks every list a block keeps alive, and with a list per message that walk cost more
    than the rest of the tap. The rest follows from the schedule: a request of shape ``phase × stages + stage``
    commands the subsystems that start there and awaits those due there (``jacobi.schedule``), a status comes with
    each stage-0 request but the run's first, and a subsystem's k-th reply answers its k-th command (its step: the
    command's tick plus its ratio). A generated loop (``manager.scheme.compiled``) appends the same values a block of
    steps at a time, as arrays (``append_steps``), which are handed over as they are."""

    def __init__(self, tap, plan: Plan, status: bool, stages: list[tuple]) -> None:
        self.tap = tap
        self.plan = plan
        n = len(plan.subsystems)
        self.names = tuple(s.name for s in plan.subsystems)
        self.status = status  # the run reports its status (each stage-0 request but the first carries it)
        self.n_stages = len(plan.stages)
        # per request shape: the subsystems it commands and those whose replies it awaits (plan indices; and as masks)
        shaped = [stage for phase_stages, _ in stages for stage in phase_stages]
        self.commanded = [tuple(s.index for s in stage[0]) for stage in shaped]
        self.awaited = [tuple(s.index for s in stage[2]) for stage in shaped]
        self.commands_mask = np.array([[i in c for i in range(n)] for c in self.commanded], dtype=bool).reshape(-1, n)
        self.awaits_mask = np.array([[i in a for i in range(n)] for a in self.awaited], dtype=bool).reshape(-1, n)
        self.layout_of: dict[tuple, int] = {}  # layout → its number in every block
        self.ticks: list[int] = []  # the block's requests: their ticks
        self.shapes: list[int | None] = []  # and their shapes
        self.commands: list[list[float]] = [[] for _ in range(n)]  # per subsystem: its polynomials' values, flat
        self.outputs: list[list[float]] = [[] for _ in range(n)]  # per subsystem: its replies' outputs, flat
        # or, appended a block of steps at a time (append_steps; a run appends one way or the other), rows of each
        self.request_blocks: list[tuple[np.ndarray, np.ndarray]] = []  # (ticks, shapes: NaN for none)
        self.command_blocks: list[list[np.ndarray]] = [[] for _ in range(n)]
        self.output_blocks: list[list[np.ndarray]] = [[] for _ in range(n)]
        self.initial_replies = Taken(tap, plan)  # the initialisation, exchange by exchange

    def initial(self, request: Exchange, outputs: dict[SubsystemPlan, np.ndarray]) -> None:
        """As :meth:`Taken.initial`."""
        self.initial_replies.initial(request, outputs)

    def start(self) -> None:
        """The stepping loop starts: the initialisation's last replies, with a request that sends nothing."""
        if self.initial_replies.last:
            self.tap.exchange(self.initial_replies.last, Exchange({}, ()))

    def append_steps(self, first: int, commands: list[np.ndarray], outputs: list[np.ndarray]) -> None:
        """Base steps ``first`` … of a single-rate run of one stage (``manager.scheme.compiled``), appended as the
        stepping loop appends them step by step: per step a request (the run's first of no shape, every other of
        shape 0) commanding every subsystem and awaiting its reply; per subsystem a row of ``commands`` each step,
        and of ``outputs`` each step answered (all but a last one that failed or was interrupted)."""
        count = len(commands[0])
        for blocks, rows in zip(self.command_blocks, commands):
            blocks.append(rows)
        shapes = np.zeros(count)
        if first == 0 and count:  # the run's first request: of no shape
            shapes[0] = np.nan
        self.request_blocks.append((np.arange(first, first + count), shapes))
        for blocks, rows in zip(self.output_blocks, outputs):
            blocks.append(rows)

    @property
    def requests(self) -> int:
        """Requests appended since the last block was handed over."""
        return len(self.ticks) + sum(len(ticks) for ticks, _ in self.request_blocks)

    def end(self, status: int | None) -> None:
        """The run has ended: the replies of the last request, with the last status."""
        self.flush(last=True, status=status is not None)

    def failed(self) -> None:
        """The run ended in the last request: the block up to its commands (the replies it awaits never came)."""
        self.flush(answered=False)

    def flush(self, last: bool = False, answered: bool = True, status: bool = False) -> None:
        """Hand the block over (nothing when it holds no request), ended by the replies of its last request
        (``answered``; with the run's last status: ``status``); ``last``: the run's last. The block holds the
        replies its requests hand over (not those of a last request that the scheme never took: a run that failed
        or was interrupted), and it is built before anything is cleared, so that an interrupt while it is built
        leaves it whole for ``failed``."""
        if self.request_blocks:
            ticks = np.concatenate([ticks for ticks, _ in self.request_blocks])
            shapes = np.concatenate([shapes for _, shapes in self.request_blocks])
        else:
            count = min(len(self.ticks), len(self.shapes))  # requests made (an interrupt may fall between the two)
            ticks = np.array(self.ticks[:count], dtype=np.int64)
            shapes = np.array(self.shapes[:count], dtype=float)  # the run's first request: None, here NaN
        count = len(ticks)
        if not count and not status:
            return
        first = np.isnan(shapes)
        shapes = np.where(first, 0, shapes).astype(np.int64)  # ... of shape 0, without the status
        before = np.concatenate(([-1], shapes[:-1])) if count else shapes  # each request follows the replies of the
        # one before it; the block's first, none (the block before ended with them)
        carries = (shapes % self.n_stages == 0) & ~first & self.status
        n_shapes = len(self.commanded)
        codes = (before + 1) * (2 * n_shapes) + carries * n_shapes + shapes
        # the codes that occur, in order, and each request's place among them (np.unique's, without its sort)
        kinds = np.flatnonzero(np.bincount(codes, minlength=1))
        place = np.zeros(kinds[-1] + 1 if len(kinds) else 1, dtype=np.intp)
        place[kinds] = np.arange(len(kinds))
        kind_of = place[codes]
        numbers = [self._layout(self.awaited[code // (2 * n_shapes) - 1] if code >= 2 * n_shapes else (),
                                bool(code % (2 * n_shapes) >= n_shapes), self.commanded[code % n_shapes])
                   for code in kinds.tolist()]
        order = np.array(numbers, dtype=np.uint32)[kind_of]
        statuses = int(carries.sum())
        # replies each subsystem hands over in the block: per shape, the requests after one of that shape
        handed = np.bincount(before[before >= 0], minlength=n_shapes) @ self.awaits_mask.astype(np.int64)
        due = self.awaited[shapes[-1]] if count and answered else ()
        if due or status:
            order = np.append(order, np.uint32(self._layout(due, status, ())))
            statuses += status
            handed[list(due)] += 1
        layouts = list(self.layout_of)
        subsystems = []
        for s in self.plan.subsystems:
            i, width, k = s.index, (s.order + 1) * len(s.inputs), int(handed[s.index])
            sent, n_outputs = ticks[self.commands_mask[:, i][shapes]], len(s.outputs)
            subsystems.append(SubsystemSteps(
                sent, _rows(self.commands[i], self.command_blocks[i], width, len(sent)), s.order + 1,
                sent[:k] + s.ratio, _rows(self.outputs[i], self.output_blocks[i], n_outputs, k)))
        block = StepsBlock(self.names, self.plan.base_step_ns, layouts, order, subsystems, statuses, last)
        for kept in (self.commands, self.outputs, self.command_blocks, self.output_blocks, [self.request_blocks]):
            for each in kept:
                each.clear()
        self.ticks.clear()
        self.shapes.clear()
        self.tap.take_steps(block)

    def _layout(self, replying: tuple[int, ...], status: bool, commanded: tuple[int, ...]) -> int:
        """The number of the layout (subsystems replying, status, subsystems commanded: plan indices)."""
        return self.layout_of.setdefault((replying, status, commanded), len(self.layout_of))


def _rows(values: list[float], blocks: list[np.ndarray], width: int, count: int) -> np.ndarray:
    """The first ``count`` rows of ``width`` values: of the flat ``values`` or the row ``blocks``."""
    if blocks:
        return np.concatenate(blocks)[:count]
    return np.array(values[:count * width], dtype=float).reshape(count, width)
