"""Explicit Jacobi co-simulation, single- and multi-rate (paper 002 Fig. 1; paper 000 §2.1).

The scheme is written as a plain loop that *yields* the messages to send and the subsystems whose
replies it needs next; a bus drives it (in-process calls, or Zenoh publications and callbacks).
Both buses therefore execute the same arithmetic in the same order.

One base macro-step [t_j, t_j+1]:
1. every subsystem whose communication point is t_j gets its input polynomial over its own
   communication step: for each input, the Lagrange polynomial (order ``p``) through the source's
   last ``p + 1`` samples at or before t_j (fewer at the start of the run);
2. subsystems integrate (in parallel on the Zenoh bus) and report outputs at their next point;
   outputs with direct feedthrough use the received polynomial evaluated at that point;
3. the manager commits the outputs due at t_j+1 and evaluates the residual power of every bond
   whose two sides both communicated at t_j+1 (paper 002 Eqs. 8–9, 13).

Correctors (``manager.scheme.correction``) hook into both ends: before a subsystem's input polynomial is
sent, each corrector that targets it may return an adjusted copy (the residual power is still
evaluated with the polynomial the extrapolation produced); after step 3, every corrector observes
the committed outputs and residual energies at t_j+1.
"""
from __future__ import annotations

import math
import struct
import time
from typing import Callable, Generator

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.base import (
    HISTORY_ROWS,
    PROGRESS_EVERY,
    Corrector,
    Exchange,
    OutputReader,
    RunRecord,
    SubsystemCalls,
)
from zencosim.manager.scheme.compiled import compiled_steps
from zencosim.manager.scheme.extrapolation import evaluate, lagrange_coefficients
from zencosim.manager.scheme.followed_blocks import Follow, FollowedBlocks
from zencosim.manager.scheme.lock_step import LockStep
from zencosim.manager.scheme.pacing import Releases
from zencosim.manager.scheme.replica import Tap
from zencosim.manager.scheme.residual import residual_power
from zencosim.manager.scheme.tapped import BLOCK_STEPS, Taken, TakenRows, TakenSteps, taken_for, takes_blocks
from zencosim.manager.scheme.window import RowWindow, Spill
from zencosim.manager.wire.protocol import HEADER, VERSION, Kind, encode
from zencosim.manager.wire.status import StatusReport


def _index(positions: tuple[int, ...]) -> slice | np.ndarray:
    """A slice when the positions are contiguous (cheap numpy indexing), else an index array."""
    if positions == tuple(range(positions[0], positions[-1] + 1)):
        return slice(positions[0], positions[-1] + 1)
    return np.array(positions)


def jacobi(plan: Plan, pacer=None, progress: Callable[[int], None] | None = None,
           correctors: tuple[Corrector, ...] = (), status: StatusReport | None = None,
           local: frozenset[int] | None = None, spill: Spill | None = None, direct: SubsystemCalls | None = None,
           tap: Tap | None = None, follower: bool = False) -> Generator[Exchange, dict[str, bytes], RunRecord]:
    """Run the whole co-simulation; yields :class:`Exchange` requests, returns the :class:`RunRecord`.

    With ``status``, every exchange after the first step carries the status of the step before it (its step:
    the message is taken from ``status``'s log, ``StatusReport.take``), and a last exchange without commands
    carries the status of the last step.

    ``local``: the subsystems whose commands this replica computes (a subsystem process: its own). It
    then follows only them and the sources of their inputs (``Plan.tracked``), takes only those replies,
    and evaluates only the bonds they take part in, so that its cost per step grows with its own inputs,
    not with the number of subsystems; every command it computes is bit for bit the full replica's.
    None: every subsystem (the manager's replica, the in-process bus).

    ``spill``: where a long run's arrays go as it runs (``manager.scheme.window``): the scheme then holds only
    the newest rows of each in memory. None: they are held whole.

    ``direct``: the subsystems, which the scheme then calls itself (``manager.bus.inproc.DirectCalls``: an in-process
    run): it yields nothing and hands them arrays; every value is the one the messages carry. With ``tap`` too (a
    recorded in-process run), it hands the tap the commands and the replies the subsystems would have sent, as a
    replica driving it would (``manager.scheme.replica``): encoded request by request, or their values kept in
    blocks that the recorder encodes (``manager.scheme.tapped``)."""
    subs = plan.subsystems
    base = plan.base_step_ns
    n_ticks = plan.n_ticks
    local = frozenset(range(len(subs))) if local is None else local
    tracked = plan.tracked(local)
    readers = [OutputReader(s, n_ticks // s.ratio + 1 if s.index in tracked else 0, spill) for s in subs]
    windows = [reader.window for reader in readers]
    n_bonds = len(plan.bonds)
    bond_history = HISTORY_ROWS + math.lcm(*(s.ratio for s in subs))  # a corrector reads a group's last point
    p_window = RowWindow(n_ticks + 1, n_bonds, float, np.nan, bond_history, spill, "residual-power")
    e_window = RowWindow(n_ticks + 1, n_bonds, float, np.nan, bond_history, spill, "residual-energy")
    p_res, e_res = p_window.array, e_window.array  # their rows from p_window.offset on
    p_res[0], e_res[0] = 0.0, 0.0
    last_bond_tick = [0] * n_bonds
    last_bond_energy = [0.0] * n_bonds
    residuals = [math.nan] * (2 * n_bonds)  # the status's: δP of every bond evaluated at this step's end, then δE
    releases = Releases(n_ticks, pacer, spill)
    sent: list[tuple[int, list[list[float]]] | None] = [None] * len(subs)  # (start tick, coefficient rows)
    # per feed: its source's newest sample is (tick + lead) // ratio: with Gauss–Seidel the end of a step the source
    # has taken already (the polynomial interpolates up to it), else the one at or before the step's start
    feeds = [[(f.source, subs[f.source].ratio, _index(f.outputs), _index(f.inputs), f.order,
               plan.lead(f.source, s.index)) for f in s.feeds if f.source in tracked] for s in subs]

    adjusters = [tuple(c for c in correctors if s.index in c.targets) for s in subs]
    copied = [None if adjusters[s.index] or direct else _copied_inputs(s, readers) for s in subs]
    # a ZOH polynomial's values, its sources' newest (where this replica tracks every source)
    zero_order = [gathered_inputs(s, readers) if all(f.source in tracked for f in s.feeds) else None for s in subs]
    gathered = [zero_order[s.index] if direct and not adjusters[s.index] else None for s in subs]
    unpack_inputs = [struct.Struct(f"<{len(s.inputs)}d").unpack_from for s in subs]  # a ZOH command's values

    def input_polynomial(s: SubsystemPlan, tick: int, stepping: bool = True) -> np.ndarray:
        """``s``'s input polynomial over its step from ``tick`` (``stepping`` False: the values at t_0, from every
        source's first sample)."""
        order = s.order
        coefficients = np.zeros((order + 1, len(s.inputs)))
        for source, ratio, outputs, inputs, feed_order, lead in feeds[s.index]:
            newest = (tick + lead) // ratio if stepping else 0
            window = windows[source]
            if feed_order == 0 or newest == 0:  # one sample: the constant lagrange_coefficients would give
                coefficients[0, inputs] = window.array[newest - window.offset, outputs]
                continue
            rows = lagrange_coefficients(window.array, outputs, newest, feed_order, ratio * base,
                                         (tick - newest * ratio) * base, window.offset)
            coefficients[:len(rows), inputs] = rows
        return coefficients

    # a subsystem process's replica without correctors evaluates no bond: nothing of its run reads them (the
    # manager's replica reports the residuals; a process, its steps' timing)
    everyone = frozenset(range(len(subs)))
    period, stages = schedule(plan, local, tracked, local == everyone or bool(correctors))
    # a direct run that is not paced, with no corrector and no tap that takes messages one by one, may run as one
    # generated loop (manager.scheme.compiled): then it runs every step, and this loop none
    compiled = (compiled_steps(plan, direct, tap is not None) if direct is not None and pacer is None
                and not correctors and (tap is None or takes_blocks(tap, plan, False)) else None)
    # a direct run's messages, for its tap (manager.scheme.tapped): request by request, appended to a block's lists,
    # or the generated loop's rows
    taken = (taken_for(tap, plan, pacer is not None, status is not None, stages, compiled is not None)
             if direct is not None and tap is not None else None)
    block = taken if isinstance(taken, TakenSteps) else None
    if block is not None:
        block_ticks, block_shapes, block_commands, block_outputs = block.ticks, block.shapes, block.commands, \
            block.outputs
    yield from initial_outputs(plan, readers, input_polynomial, local, tracked, direct, taken)
    if isinstance(taken, TakenSteps | TakenRows):
        taken.start()
    if block is not None:
        handover_at = block.handed_over(time.perf_counter_ns(), BLOCK_STEPS)  # the loop starts
    n_stages = len(plan.stages)
    some_bonds_idle = [len(bonds) < n_bonds for _, bonds in stages]  # their status fields are NaN (multi-rate)
    step_s = base * 1e-9
    step_status = None  # the step whose status the next exchange reports
    log_residuals, log_times = (status.log_residuals, status.log_times) if status is not None else (None, None)
    header = HEADER.pack
    step_kind = int(Kind.STEP)
    stepping: list[tuple[SubsystemPlan, np.ndarray]] = []  # direct: the steps to call once released
    computed: list[np.ndarray | None] = [None] * len(subs)  # direct: the outputs each subsystem's step computed
    # a subsystem process's replica that does nothing but step its subsystem on its sources' newest outputs hands its
    # steps to the replica in one request (manager.scheme.lock_step)
    lock_step = (lock_step_request(plan, local, tracked, readers, copied, releases.release)
                 if direct is None and not correctors and status is None and progress is None and period == 1 else None)

    # the manager's replica of an unrecorded single-rate zero-order run takes whole steps at a time
    follow = (FollowedBlocks(plan, readers, p_window, e_window, last_bond_energy, last_bond_tick, releases.times,
                             progress)
              if follower and not correctors and status is None and pacer is None and period == 1
              and not plan.sequential and all(segments is not None for segments in copied) else None)

    try:
        first_tick = 0
        if follow is not None:  # blocks of steps while each is what the scheme expects; from the first that is not, one
            while first_tick < n_ticks:  # step at a time (the replica queues that block again)
                block = yield Follow(first_tick, n_ticks)
                if not follow.take(block, first_tick):
                    break
                first_tick += len(block[subs[0].name])
        if compiled is not None:
            first_tick = compiled.run(readers, p_window, e_window, releases.times, progress, taken)
            step_status = first_tick if status is not None else None
        if lock_step is not None:  # every step in lock step (its record: the release times; the manager's, the rest)
            yield lock_step
            first_tick = n_ticks
        for tick in range(first_tick, n_ticks):
            phase = tick % period
            next_tick = tick + 1
            released_ns = None
            for number, (starting, partners_starting, due, due_names, due_span) in enumerate(stages[phase][0]):
                sends = {}
                for s in starting:
                    segments = copied[s.index]
                    if segments is not None:  # ZOH: the sources' newest values, as they arrived
                        payload = b"".join([reader.newest_bytes[start:end] for reader, start, end in segments])
                        command = header(VERSION, step_kind, 1, len(s.inputs), tick, tick * base, 0) + payload
                        sends[s.name] = command
                        sent[s.index] = (tick, [unpack_inputs[s.index](command, HEADER.size)])
                        continue
                    sources = gathered[s.index]
                    if sources is not None:  # direct ZOH: the same values, as floats
                        values = [reader.newest[output] for reader, output in sources]
                        sent[s.index] = (tick, [values])
                        stepping.append((s, values))
                        continue
                    coefficients = input_polynomial(s, tick)
                    sent[s.index] = (tick, coefficients.tolist())
                    for corrector in adjusters[s.index]:
                        coefficients = corrector.adjust(s.index, tick, coefficients)
                    if direct is None:
                        sends[s.name] = encode(Kind.STEP, tick, tick * base, coefficients, s.order + 1)
                    else:
                        stepping.append((s, coefficients))
                for s in partners_starting:  # the other side of a local bond: its polynomial, for the residual
                    sources = zero_order[s.index]
                    sent[s.index] = (tick, [[reader.newest[output] for reader, output in sources]]
                                     if sources is not None else input_polynomial(s, tick).tolist())
                if released_ns is None:
                    released_ns = releases.release(tick)
                elif not (starting or partners_starting or due):  # its subsystem is amid a longer step (Gauss–Seidel)
                    continue
                due_step = tick + due_span  # the step of the replies this stage takes
                # a request's names repeat with its stage and phase (after the first: the requests before them do)
                shape = phase * n_stages + number if tick or number else None
                if direct is None:
                    replies = yield Exchange(sends, due_names, None if number else step_status, due_step, shape)
                    for s in due:
                        readers[s.index].commit(replies[s.name], due_step)
                    continue
                if block is not None:  # its commands, then the request (TakenSteps: nothing called per step)
                    # a period starts (every command answered): a full block, or what a slow loop holds
                    if shape == 0 and len(block_ticks) >= handover_at:
                        handover_at = block.handed_over(released_ns, BLOCK_STEPS)
                    for s, coefficients in stepping:
                        block_commands[s.index].extend(coefficients if type(coefficients) is list
                                                       else coefficients.ravel().tolist())
                    block_ticks.append(tick)
                    block_shapes.append(shape)
                elif taken is not None:
                    taken.request(stepping, due_names, None if number else step_status, due_step, shape, due, tick)
                for s, coefficients in stepping:
                    y = computed[s.index] = direct.step(s, tick, coefficients)
                    if block is not None:
                        block_outputs[s.index].extend(y if type(y) is list else y.tolist())
                    elif taken is not None:
                        taken.reply(s, tick + s.ratio, y)
                stepping.clear()
                for s in due:
                    readers[s.index].commit_values(computed[s.index], due_step)
            if next_tick >= p_window.end:
                p_window.advance(next_tick)
                e_window.advance(next_tick)
            row = next_tick - p_window.offset
            if some_bonds_idle[phase]:
                residuals = [math.nan] * (2 * n_bonds)
            for b, bond, components in stages[phase][1]:
                delta_p = bond_residual_power(readers, sent, bond, components, next_tick, step_s)
                p_res[row, b] = residuals[b] = delta_p
                e_res[row, b] = last_bond_energy[b] = residuals[n_bonds + b] = (
                    last_bond_energy[b] + delta_p * (next_tick - last_bond_tick[b]) * step_s)
                last_bond_tick[b] = next_tick
            for corrector in correctors:
                corrector.observe(next_tick, windows, e_window)
            if status is not None:  # logged, encoded when a tap takes it (manager.wire.status)
                log_residuals(residuals)
                log_times((next_tick, released_ns, time.perf_counter_ns(),
                           0 if pacer is None else pacer.last_lateness_ns))
                step_status = next_tick
            if progress is not None and next_tick % PROGRESS_EVERY == 0:
                progress(next_tick)
    except BaseException:
        if taken is not None:  # what the tap of a replica had seen when the run ended here
            taken.failed()
        raise
    if direct is None and step_status is not None:
        yield Exchange({}, (), step_status)
    if taken is not None:
        taken.end(step_status)

    return RunRecord(plan, [w.finish() for w in windows], p_window.finish(), e_window.finish(), *releases.finish(),
                     0 if pacer is None else pacer.missed, tuple(entry for c in correctors for entry in c.log()))


def _copied_inputs(s: SubsystemPlan, readers: list[OutputReader]) -> tuple[tuple[OutputReader, int, int], ...] | None:
    """For a subsystem with zero-order inputs, every input fed once (``SubsystemPlan.zero_order_sources``): where its
    input values lie in its sources' newest replies, as byte ranges ``(reader of the source, start, end)`` in input
    order, adjacent ranges merged (the command's values are then these bytes, unchanged). None otherwise."""
    sources = s.zero_order_sources
    if sources is None:
        return None
    segments: list[list[int]] = []
    for source, output in sources:
        start = HEADER.size + 8 * output
        if segments and segments[-1][0] == source and segments[-1][2] == start:
            segments[-1][2] = start + 8
        else:
            segments.append([source, start, start + 8])
    return tuple((readers[source], start, end) for source, start, end in segments)


def lock_step_request(plan: Plan, local: frozenset[int], tracked: frozenset[int], readers: list[OutputReader],
                      copied: list, release: Callable[[int], int]) -> LockStep | None:
    """The :class:`LockStep` request of a replica that computes one subsystem's commands (a subsystem process) from
    zero-order inputs copied from its sources' replies (``_copied_inputs``), single-rate Jacobi; None otherwise (the
    manager's replica, and an in-process one, follow every subsystem: their record is the run's)."""
    if len(local) != 1 or len(plan.subsystems) == 1 or plan.sequential:
        return None
    (own,) = local
    segments = copied[own]
    if segments is None:
        return None
    subs = plan.subsystems
    return LockStep(subs[own], tuple(subs[i] for i in sorted(tracked)),
                    {subs[i].name: readers[i].newest_bytes for i in tracked},
                    tuple((reader.sub.name, start, end) for reader, start, end in segments),
                    0, plan.n_ticks, plan.base_step_ns, release)


def gathered_inputs(s: SubsystemPlan, readers: list[OutputReader]) -> tuple[tuple[OutputReader, int], ...] | None:
    """As ``_copied_inputs`` for the direct path: per input, ``(reader of its source, output index)``, the value in
    the source's newest outputs as floats (``OutputReader.newest``). None otherwise."""
    sources = s.zero_order_sources
    return None if sources is None else tuple((readers[source], output) for source, output in sources)


def initial_outputs(plan: Plan, readers: list[OutputReader], input_polynomial, local: frozenset[int],
                     tracked: frozenset[int], direct: SubsystemCalls | None, taken: Taken | TakenSteps | None
                     ) -> Generator[Exchange, dict[str, bytes], None]:
    """The outputs at t_0, round by round as the plan orders them (``manager.plan.run_plan._init_rounds``):
    each request carries the inputs whose sources are final, 0 for the others; a subsystem's row at t_0 is
    its last reply. Requests go to the ``local`` subsystems; the replies of the ``tracked`` ones are taken
    (``direct``: the subsystems are called, as ``jacobi`` says)."""
    subs = plan.subsystems
    for round_ in plan.init_rounds:
        sends, computed = {}, {}
        for step in round_:
            if step.subsystem not in local:
                continue
            s = subs[step.subsystem]
            w0 = np.zeros((1, len(s.inputs)))
            if step.ready:
                w0[0, list(step.ready)] = input_polynomial(s, 0, stepping=False)[0, list(step.ready)]
            if direct is None or taken is not None:
                sends[s.name] = encode(Kind.INIT, 0, 0, w0, rows=1)
            if direct is not None:
                computed[s.index] = direct.initial(s, w0[0])
        awaited = [step.subsystem for step in round_ if step.subsystem in tracked]
        if direct is not None:
            for i in awaited:
                readers[i].commit_values(computed[i], 0)
            if taken is not None:  # the request, then its replies, as the tap of a replica sees them
                taken.initial(Exchange(sends, tuple(subs[i].name for i in awaited), None, 0),
                              {subs[i]: computed[i] for i in awaited})
            continue
        replies = yield Exchange(sends, tuple(subs[i].name for i in awaited), None, 0)
        for i in awaited:
            readers[i].commit(replies[subs[i].name], 0)


def schedule(plan: Plan, local: frozenset[int], tracked: frozenset[int], bonds: bool = True) -> tuple:
    """What happens at each phase of the schedule, which repeats every lcm of the ratios: ``(period, phases)``, each
    phase ``(stages, bonds)``: per stage of the plan (``Plan.stages``) the local subsystems starting a step, the
    non-local sides of their bonds starting one (whose input polynomial the residual power needs: the columns
    this replica can compute are those it needs), the tracked subsystems whose replies the stage takes, their names,
    and how many base steps after the phase's start those replies' step is; then the bonds of local subsystems
    evaluated at the phase's end (none without ``bonds``).

    Jacobi (one stage) takes a subsystem's reply at the end of its step's last phase (1 base step on); Gauss–Seidel
    takes it in the stage where the step starts (its ratio on), so that the later stages' input polynomials reach
    its sample at the step's end: a slower subsystem stepping first gives the faster ones its outputs to
    interpolate through its whole step, and a faster one stepping first gives the slower one its newest sample."""
    subs = plan.subsystems
    period = math.lcm(*(s.ratio for s in subs))
    evaluated = plan.bonds if bonds else ()
    partners = {side for bond in evaluated if {bond.force_side, bond.motion_side} & local
                for side in (bond.force_side, bond.motion_side)} - local
    phases = []
    for phase in range(period):
        stages = []
        for stage in plan.stages:
            members = [subs[i] for i in stage]
            if plan.sequential:  # one subsystem per stage: its reply is taken where its step starts
                due = tuple(s for s in members if phase % s.ratio == 0 and s.index in tracked)
                span = members[0].ratio
            else:
                due = tuple(s for s in members if (phase + 1) % s.ratio == 0 and s.index in tracked)
                span = 1
            stages.append((tuple(s for s in members if phase % s.ratio == 0 and s.index in local),
                           tuple(s for s in members if phase % s.ratio == 0 and s.index in partners),
                           due, tuple(s.name for s in due), span))
        phase_bonds = tuple((b, bond, bond.components) for b, bond in enumerate(evaluated)
                            if (phase + 1) % subs[bond.force_side].ratio == 0
                            and (phase + 1) % subs[bond.motion_side].ratio == 0
                            and {bond.force_side, bond.motion_side} & local)
        phases.append((tuple(stages), phase_bonds))
    return period, phases


def bond_residual_power(readers: list[OutputReader], sent: list, bond, components, tick: int, step_s: float) -> float:
    """δP of ``bond`` at ``tick`` (paper 002 Eqs. 8–9) from both sides' committed outputs and the input
    polynomials they received; a vector bond's residual power is the dot product: the sum over its components."""
    f_start, f_coefficients = sent[bond.force_side]
    m_start, m_coefficients = sent[bond.motion_side]
    f_row = readers[bond.force_side].newest
    m_row = readers[bond.motion_side].newest
    f_tau, m_tau = (tick - f_start) * step_s, (tick - m_start) * step_s
    f_constant, m_constant = len(f_coefficients) == 1, len(m_coefficients) == 1  # ZOH: the value, no call
    delta_p = 0.0
    for force, velocity_input, force_input, velocity in components:
        delta_p += residual_power(
            f_row[force],
            f_coefficients[0][velocity_input] if f_constant else evaluate(f_coefficients, velocity_input, f_tau),
            m_coefficients[0][force_input] if m_constant else evaluate(m_coefficients, force_input, m_tau),
            m_row[velocity])
    return delta_p
