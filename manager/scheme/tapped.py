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
docs/recording.md, benchmarks/bench_instructions.py --recording). A generated loop (``manager.scheme.compiled``)
hands :class:`TakenRows` the rows it makes anyway, as :class:`RowsBlock` (the recorder's ``take_rows``), from which
the recorder's processes build the same messages (``recordings.rows_frame``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.base import Exchange
from zencosim.manager.scheme.replica import Tap
from zencosim.manager.wire.arrays import float64s
from zencosim.manager.wire.protocol import Kind, command_ref, encode

BLOCK_STEPS = 256  # requests of the stepping loop handed over at once (TakenSteps)
LONGEST_PERIOD = 16 * BLOCK_STEPS  # base steps: a longer schedule period is tapped exchange by exchange
# what a direct run's loop holds and has not handed over is handed over, the block full or not, once it holds
# HANDOVER_STEPS requests, or a HANDOVER_SHARE-th of those of the loop so far, whichever is more, and the loop has
# run HANDOVER_COSTS times as long as the last such hand-over took of its CPU, or FIRST_HANDOVER_NS, whichever is
# less (_InBlocks.handed_over): on a faster host the loop waits as many steps
HANDOVER_STEPS = 16
HANDOVER_SHARE = 32
HANDOVER_COSTS = 20
FIRST_HANDOVER_NS = 1_000_000


def handover_size(done: int, full: int) -> int:
    """How much a loop that has done ``done`` requests (steps, replies) hands over at a time, at the most: a block
    (``full``), or less early in a run, so that what a process that ends takes with it stays a small part of what it
    did (``HANDOVER_STEPS``, or a ``HANDOVER_SHARE``-th of ``done``)."""
    return min(full, max(HANDOVER_STEPS, done // HANDOVER_SHARE))


def takes_blocks(tap, plan: Plan, paced: bool) -> bool:
    """Whether a direct run hands ``tap`` blocks of arrays: where the tap takes them (``take_steps``, ``take_rows``),
    the run is not paced (a real-time run's live view follows it step by step) and a block, which holds whole
    schedule periods, stays small (the lcm of the communication ratios at most ``LONGEST_PERIOD`` base steps)."""
    return not paced and hasattr(tap, "take_steps") and math.lcm(*(s.ratio for s in plan.subsystems)) <= LONGEST_PERIOD


def taken_for(tap, plan: Plan, paced: bool, status: bool, stages: list[tuple], rows: bool = False
              ) -> Taken | TakenSteps | TakenRows:
    """What hands a direct run's messages to ``tap``: the rows of a generated loop (``rows``, where the run
    :func:`takes_blocks`), blocks of arrays where it takes blocks, else exchange by exchange. ``status``: the run
    reports its status; ``stages``: its schedule's phases (``manager.scheme.jacobi.schedule``)."""
    if not takes_blocks(tap, plan, paced):
        return Taken(tap, plan)
    return TakenRows(tap, plan, status) if rows else TakenSteps(tap, plan, status, stages)


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


class _InBlocks:
    """What :class:`TakenSteps` and :class:`TakenRows` share: the initialisation goes to ``tap`` exchange by exchange
    (:class:`Taken`), the stepping loop's exchanges in blocks (each subclass's ``flush``)."""

    def __init__(self, tap, plan: Plan) -> None:
        self.tap = tap
        self.initial_replies = Taken(tap, plan)  # the initialisation, exchange by exchange
        self.handed_ns: int | None = None  # when the stepping loop last handed something over (``handed_over``)
        self.soonest_ns = FIRST_HANDOVER_NS  # [ns] of the loop after it, what a block not full holds is handed over

    def initial(self, request: Exchange, outputs: dict[SubsystemPlan, np.ndarray]) -> None:
        """As :meth:`Taken.initial`."""
        self.initial_replies.initial(request, outputs)

    def start(self) -> None:
        """The stepping loop starts: the initialisation's last replies, with a request that sends nothing."""
        if self.initial_replies.last:
            self.tap.exchange(self.initial_replies.last, Exchange({}, ()))

    def handed_over(self, now_ns: int, full: int) -> int:
        """The stepping loop, at ``now_ns`` (perf_counter_ns) where a period starts, holds what a block of ``full``
        requests does: hand the block over when it is full, else what it holds once the loop has run ``soonest_ns``
        since the last hand-over (``hand_over``): ``HANDOVER_COSTS`` times the CPU time the last that was not full
        took, at most ``FIRST_HANDOVER_NS``. Returns the requests the loop is to hold when it calls again:
        ``handover_size`` more than it holds after this call, at most ``full``.

        So a model that ends the run's process (``os._exit``, a segmentation fault) takes with it at most the
        larger of ``HANDOVER_STEPS``, ``1 / HANDOVER_SHARE`` of the steps computed and the steps the loop computes
        in ``soonest_ns`` (a few tens of a slow model's, no more on a faster host), and a loop whose steps fill a
        block sooner hands over what it did before (one call more per ``handover_size`` requests). Its first call
        (the loop starts) hands over nothing."""
        requests = self.requests
        if self.handed_ns is None:
            self.handed_ns = now_ns
        elif requests >= full:
            self.hand_over(True)
            self.handed_ns = now_ns
        elif now_ns - self.handed_ns >= self.soonest_ns:
            cpu_ns = time.thread_time_ns()
            self.hand_over(False)
            self.soonest_ns = min(FIRST_HANDOVER_NS, HANDOVER_COSTS * (time.thread_time_ns() - cpu_ns))
            self.handed_ns = time.perf_counter_ns()
        held = self.requests
        return min(full, held + handover_size(self.handed + held, full))

    def hand_over(self, full: bool) -> None:
        """Hand the block over (``flush``), ``full`` or not."""
        self.flush()

    def end(self, status: int | None) -> None:
        """The run has ended: the replies of the last request, with the last status."""
        self.flush(last=True, status=status is not None)

    def failed(self) -> None:
        """The run ended in the last request: the block up to its commands (the replies it awaits never came)."""
        self.flush(answered=False)


class TakenSteps(_InBlocks):
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
    command's tick plus its ratio). A generated loop (``manager.scheme.compiled``) hands its rows to
    :class:`TakenRows` instead."""

    def __init__(self, tap, plan: Plan, status: bool, stages: list[tuple]) -> None:
        super().__init__(tap, plan)
        shaped = [stage for phase_stages, _ in stages for stage in phase_stages]
        self._follow(StepsSchedule(
            tuple(s.name for s in plan.subsystems), plan.base_step_ns, len(plan.stages), status,
            tuple(tuple(s.index for s in stage[0]) for stage in shaped),
            tuple(tuple(s.index for s in stage[2]) for stage in shaped),
            tuple((s.order + 1, len(s.inputs), len(s.outputs), s.ratio) for s in plan.subsystems)))

    @classmethod
    def following(cls, schedule: StepsSchedule, tap) -> TakenSteps:
        """Blocks of a run of ``schedule`` for ``tap`` (a recorder's process: :func:`pending_block`), without its
        initialisation."""
        taken = cls.__new__(cls)
        taken.tap = tap
        taken._follow(schedule)
        return taken

    def _follow(self, schedule: StepsSchedule) -> None:
        """Take a run of ``schedule``'s requests."""
        self.schedule = schedule
        n = len(schedule.names)
        self.names = schedule.names
        self.status = schedule.status  # the run reports its status (each stage-0 request but the first carries it)
        self.n_stages = schedule.n_stages
        # per request shape: the subsystems it commands and those whose replies it awaits (plan indices; and as masks)
        self.commanded = list(schedule.commanded)
        self.awaited = list(schedule.awaited)
        self.commands_mask = np.array([[i in c for i in range(n)] for c in self.commanded], dtype=bool).reshape(-1, n)
        self.awaits_mask = np.array([[i in a for i in range(n)] for a in self.awaited], dtype=bool).reshape(-1, n)
        self.layout_of: dict[tuple, int] = {}  # layout → its number in every block
        self.ticks: list[int] = []  # the block's requests: their ticks
        self.shapes: list[int | None] = []  # and their shapes
        self.commands: list[list[float]] = [[] for _ in range(n)]  # per subsystem: its polynomials' values, flat
        self.outputs: list[list[float]] = [[] for _ in range(n)]  # per subsystem: its replies' outputs, flat
        self.pending_from = (0, [0] * n, [0] * n)  # the requests, values and outputs handed over as pending
        self.handed = 0  # the requests of the blocks handed over

    def flush(self, last: bool = False, answered: bool = True, status: bool = False) -> None:
        """Hand the block over (nothing when it holds no request), ended by the replies of its last request
        (``answered``; with the run's last status: ``status``); ``last``: the run's last. The block holds the
        replies its requests hand over (not those of a last request that the scheme never took: a run that failed
        or was interrupted), and it is built before anything is cleared, so that an interrupt while it is built
        leaves it whole for ``failed``."""
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
        for i, (rows, n_inputs, n_outputs, ratio) in enumerate(self.schedule.subsystems):
            sent, k = ticks[self.commands_mask[:, i][shapes]], int(handed[i])
            subsystems.append(SubsystemSteps(sent, _rows(self.commands[i], rows * n_inputs, len(sent)), rows,
                                             sent[:k] + ratio, _rows(self.outputs[i], n_outputs, k)))
        block = StepsBlock(self.names, self.schedule.base_step_ns, layouts, order, subsystems, statuses, last)
        for kept in (self.commands, self.outputs):
            for each in kept:
                each.clear()
        self.ticks.clear()
        self.shapes.clear()
        self.pending_from = (0, [0] * len(self.names), [0] * len(self.names))
        self.handed += count
        self.tap.take_steps(block)

    @property
    def requests(self) -> int:
        """Requests taken since the last block was handed over."""
        return len(self.ticks)

    def hand_over(self, full: bool) -> None:
        """Hand the block over when it is ``full`` (``flush``), else what it took since it last handed something
        over, as a :class:`PendingSteps` to ``tap.take_pending``: slices of its lists, no block. The recorder's process
        keeps them and builds their block (:meth:`pending_block`) only when the run's process ended before it handed
        the block over (a model that ended it)."""
        if full:
            self.flush()
            return
        requests, commands, outputs = self.pending_from
        self.tap.take_pending(PendingSteps(self.schedule, self.ticks[requests:], self.shapes[requests:],
                                           [c[at:] for c, at in zip(self.commands, commands)],
                                           [o[at:] for o, at in zip(self.outputs, outputs)]))
        self.pending_from = (len(self.ticks), [len(c) for c in self.commands], [len(o) for o in self.outputs])

    @classmethod
    def pending_block(cls, pending: list[PendingSteps]) -> StepsBlock | None:
        """The block the loop would have handed over where it took the last of ``pending``, those it took since its
        last block (:meth:`hand_over`), as ``flush`` builds it there, every command answered; None without requests."""
        blocks: list[StepsBlock] = []
        taken = cls.following(pending[0].schedule, _Blocks(blocks))
        for part in pending:
            taken.ticks += part.ticks
            taken.shapes += part.shapes
            for kept, values in zip(taken.commands + taken.outputs, [*part.commands, *part.outputs]):
                kept += values
        taken.flush()
        return blocks[0] if blocks else None

    def _layout(self, replying: tuple[int, ...], status: bool, commanded: tuple[int, ...]) -> int:
        """The number of the layout (subsystems replying, status, subsystems commanded: plan indices)."""
        return self.layout_of.setdefault((replying, status, commanded), len(self.layout_of))


class StepsSchedule(NamedTuple):
    """What :class:`TakenSteps` knows of a run (plain values: a recorder's process rebuilds it from them)."""

    names: tuple[str, ...]  # the subsystems, by plan index
    base_step_ns: int
    n_stages: int
    status: bool  # the run reports its status
    commanded: tuple[tuple[int, ...], ...]  # per request shape: the subsystems it commands
    awaited: tuple[tuple[int, ...], ...]  # and those whose replies it awaits
    subsystems: tuple[tuple[int, int, int, int], ...]  # per subsystem: rows of its polynomials, inputs, outputs, ratio


class PendingSteps(NamedTuple):
    """Requests a :class:`TakenSteps` took since it last handed something over, not yet handed over as a block
    (:meth:`TakenSteps.hand_over`): its lists' new values."""

    schedule: StepsSchedule
    ticks: list[int]
    shapes: list[int | None]
    commands: list[list[float]]
    outputs: list[list[float]]


class _Blocks:
    """A tap that keeps the blocks it takes in ``blocks``."""

    def __init__(self, blocks: list[StepsBlock]) -> None:
        self.take_steps = blocks.append


def _rows(values: list[float], width: int, count: int) -> np.ndarray:
    """The first ``count`` rows of ``width`` values of the flat ``values``."""
    return float64s(values[:count * width]).reshape(count, width)


@dataclass
class RowsBlock:
    """Macro-steps of a generated loop (``manager.scheme.compiled``): single-rate Jacobi, every subsystem commanded
    each step with its sources' newest outputs (zero-order) and answering it. Requests ``first`` …
    ``first + requests - 1``; ``rows`` (float64, one per step: every subsystem's outputs, then every bond's δP, then
    its δE), the first carried (the step before ``first``: its outputs command request 0, its residuals and times are
    the status request 0 reports; at the run's start, the outputs at t_0 and nothing else), then one per request
    answered by the loop; ``released``/``completed`` [ns, perf_counter_ns] of each row's step. A request's commands are
    the outputs of the row before its own (``plan.subsystems[i].zero_order_sources``). ``answered``: the last request's
    replies are handed over (not those of a run that failed or was interrupted in it); ``end_status``: the run's last
    status follows them; ``status``: the run reports its status (each request but the run's first carries the
    status of the step it starts); ``start_ns``: the release of step 0; ``last``: the run's last block."""

    first: int
    requests: int
    rows: list[np.ndarray]  # blocks of rows, one after the other, the carried row first
    released: list[np.ndarray]
    completed: list[np.ndarray]
    answered: bool
    end_status: bool
    status: bool
    start_ns: int
    last: bool

    @property
    def replies(self) -> int:
        """Replies of each subsystem handed over."""
        return rows_replies(self.requests, self.answered)

    @property
    def status_steps(self) -> range:
        """The steps whose statuses the block's requests report (and, with ``end_status``, the run's last)."""
        return rows_status_steps(self.first, self.requests, self.end_status, self.status)


def rows_replies(requests: int, answered: bool) -> int:
    """The replies of each subsystem a :class:`RowsBlock` of ``requests`` hands over (the last request's only if
    ``answered``); the recorder counts them and its processes build them (``recordings.rows_frame``)."""
    return max(0, requests - 1 + answered)


def rows_status_steps(first: int, requests: int, end_status: bool, status: bool) -> range:
    """The steps whose statuses a :class:`RowsBlock` (its fields) reports: each request's but the run's first (of the
    step it starts), and with ``end_status`` the run's last; none where the run reports no status."""
    return range(max(first, 1), first + requests + end_status) if status else range(0)


class TakenRows(_InBlocks):
    """What a generated loop (``manager.scheme.compiled``) hands a tap that takes rows (``tap.take_rows``): the rows it
    makes anyway for the run's windows, a :class:`RowsBlock` about every ``TAP_BLOCK_STEPS`` steps, when the run
    ends and when it fails. The messages are built from them by the recorder's processes
    (``recordings.rows_frame``), so a recorded run's stepping loop is the unrecorded one's (issue 26). The
    initialisation goes exchange by exchange, as :class:`TakenSteps` hands it."""

    def __init__(self, tap, plan: Plan, status: bool) -> None:
        super().__init__(tap, plan)
        self.status = status
        self.first = 0  # the first request of the block
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (rows, released, completed) appended
        self.carried: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # the row before the block's first
        self.start_ns = 0  # the release of step 0
        self.pending = False  # a request made after the rows, never answered

    def starts_from(self, outputs: list[float], width: int) -> None:
        """The loop starts from ``outputs`` (every subsystem's at t_0, flat) in rows of ``width``."""
        row = np.full((1, width), np.nan)
        row[0, :len(outputs)] = outputs
        self.carried = (row, np.zeros(1, np.int64), np.zeros(1, np.int64))

    def append_rows(self, rows: np.ndarray, released: np.ndarray, completed: np.ndarray) -> None:
        """The loop's next steps: their ``rows`` (kept, not copied) and their release and completion times."""
        if not self.blocks and self.first == 0 and len(released):
            self.start_ns = int(released[0])
        self.blocks.append((rows, released, completed))

    def unanswered(self) -> None:
        """The loop made one more request after its rows (its commands: the last row's outputs), which failed."""
        self.pending = True

    @property
    def handed(self) -> int:
        """The requests of the blocks handed over."""
        return self.first

    @property
    def requests(self) -> int:
        """Requests appended since the last block was handed over."""
        return sum(len(rows) for rows, _, _ in self.blocks) + self.pending

    def flush(self, last: bool = False, answered: bool = True, status: bool = False) -> None:
        """Hand the block over (nothing when it holds no request); the arguments as :meth:`TakenSteps.flush`'s."""
        requests = self.requests
        if not requests:
            return
        carried = self.carried
        block = RowsBlock(self.first, requests, [carried[0], *(rows for rows, _, _ in self.blocks)],
                          [carried[1], *(times for _, times, _ in self.blocks)],
                          [carried[2], *(times for _, _, times in self.blocks)], answered, status, self.status,
                          self.start_ns, last)
        if self.blocks:
            rows, released, completed = self.blocks[-1]
            self.carried = (rows[-1:], released[-1:], completed[-1:])
        self.first += requests
        self.blocks = []
        self.pending = False
        self.tap.take_rows(block)
