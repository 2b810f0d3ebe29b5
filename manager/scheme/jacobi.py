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
from zencosim.manager.scheme.base import PROGRESS_EVERY, Corrector, Exchange, OutputReader, RunRecord
from zencosim.manager.scheme.extrapolation import evaluate, lagrange_coefficients
from zencosim.manager.scheme.residual import residual_power
from zencosim.manager.wire.protocol import HEADER, VERSION, Kind, encode
from zencosim.manager.wire.status import StatusReport


def _index(positions: tuple[int, ...]) -> slice | np.ndarray:
    """A slice when the positions are contiguous (cheap numpy indexing), else an index array."""
    if positions == tuple(range(positions[0], positions[-1] + 1)):
        return slice(positions[0], positions[-1] + 1)
    return np.array(positions)


def jacobi(plan: Plan, pacer=None, progress: Callable[[int], None] | None = None,
           correctors: tuple[Corrector, ...] = (), status: StatusReport | None = None
           ) -> Generator[Exchange, dict[str, bytes], RunRecord]:
    """Run the whole co-simulation; yields :class:`Exchange` requests, returns the :class:`RunRecord`.

    With ``status``, every exchange after the first step carries the status of the step before it, and
    a last exchange without commands carries the status of the last step."""
    subs = plan.subsystems
    base = plan.base_step_ns
    n_ticks = plan.n_ticks
    readers = [OutputReader(s, n_ticks // s.ratio + 1) for s in subs]
    traj = [reader.trajectory for reader in readers]
    n_bonds = len(plan.bonds)
    p_res = np.full((n_ticks + 1, n_bonds), np.nan)
    e_res = np.full((n_ticks + 1, n_bonds), np.nan)
    p_res[0], e_res[0] = 0.0, 0.0
    last_bond_tick = [0] * n_bonds
    last_bond_energy = [0.0] * n_bonds
    send_time = np.zeros(n_ticks, dtype=np.int64)
    sent: list[tuple[int, list[list[float]]] | None] = [None] * len(subs)  # (start tick, coefficient rows)
    feeds = [[(f.source, subs[f.source].ratio, _index(f.outputs), _index(f.inputs)) for f in s.feeds] for s in subs]

    adjusters = [tuple(c for c in correctors if s.index in c.targets) for s in subs]
    copied = [None if adjusters[s.index] else _copied_inputs(s) for s in subs]

    def input_polynomial(s: SubsystemPlan, tick: int) -> np.ndarray:
        order = s.order
        coefficients = np.zeros((order + 1, len(s.inputs)))
        for source, ratio, outputs, inputs in feeds[s.index]:
            newest = tick // ratio
            rows = lagrange_coefficients(traj[source], outputs, newest, order, ratio * base, (tick - newest * ratio) * base)
            coefficients[:len(rows), inputs] = rows
        return coefficients

    yield from _initial_outputs(plan, readers, input_polynomial)
    period, starting, due, due_names, bonds_due = _schedule(plan)
    step_s = base * 1e-9
    step_status = None
    header = HEADER.pack

    for tick in range(n_ticks):
        phase = tick % period
        sends = {}
        for s in starting[phase]:
            segments = copied[s.index]
            if segments is not None:  # ZOH: the sources' newest values, as they arrived
                payload = b"".join([readers[source].newest_bytes[start:end] for source, start, end in segments])
                sends[s.name] = command = header(VERSION, Kind.STEP, 1, len(s.inputs), tick, tick * base, 0) + payload
                sent[s.index] = (tick, [_float_rows(command, len(s.inputs))])
                continue
            coefficients = input_polynomial(s, tick)
            sent[s.index] = (tick, coefficients.tolist())
            for corrector in adjusters[s.index]:
                coefficients = corrector.adjust(s.index, tick, coefficients)
            sends[s.name] = encode(Kind.STEP, tick, tick * base, coefficients, s.order + 1)
        next_tick = tick + 1
        if pacer is not None:
            pacer.wait(tick)
        send_time[tick] = released_ns = time.perf_counter_ns()
        replies = yield Exchange(sends, due_names[phase], step_status)
        for s in due[phase]:
            readers[s.index].commit(replies[s.name], next_tick)
        for b, bond, components in bonds_due[phase]:
            delta_p = _bond_residual_power(readers, sent, bond, components, next_tick, step_s)
            p_res[next_tick, b] = delta_p
            e_res[next_tick, b] = last_bond_energy[b] = (last_bond_energy[b]
                                                         + delta_p * (next_tick - last_bond_tick[b]) * step_s)
            last_bond_tick[b] = next_tick
        for corrector in correctors:
            corrector.observe(next_tick, traj, e_res)
        if status is not None:
            step_status = status.encode(next_tick, next_tick * base, p_res[next_tick], e_res[next_tick],
                                        int(send_time[0]), released_ns, time.perf_counter_ns(),
                                        None if pacer is None else int(pacer.lateness_ns[tick]))
        if progress is not None and next_tick % PROGRESS_EVERY == 0:
            progress(next_tick)
    if step_status is not None:
        yield Exchange({}, (), step_status)

    return RunRecord(plan, traj, p_res, e_res, send_time,
                     None if pacer is None else pacer.lateness_ns,
                     0 if pacer is None else pacer.missed, tuple(entry for c in correctors for entry in c.log()))


def _copied_inputs(s: SubsystemPlan) -> tuple[tuple[int, int, int], ...] | None:
    """For a subsystem with zero-order inputs, every input fed once: where its input values lie in its sources'
    newest replies, as byte ranges ``(source, start, end)`` in input order, adjacent ranges merged (the
    command's values are then these bytes, unchanged: a ZOH polynomial is the newest sample). None otherwise."""
    if s.order != 0:
        return None
    where = {}
    for feed in s.feeds:
        for output, target in zip(feed.outputs, feed.inputs):
            where[target] = (feed.source, HEADER.size + 8 * output)
    if sorted(where) != list(range(len(s.inputs))):
        return None
    segments: list[list[int]] = []
    for target in range(len(s.inputs)):
        source, start = where[target]
        if segments and segments[-1][0] == source and segments[-1][2] == start:
            segments[-1][2] = start + 8
        else:
            segments.append([source, start, start + 8])
    return tuple(map(tuple, segments))


def _initial_outputs(plan: Plan, readers: list[OutputReader], input_polynomial
                     ) -> Generator[Exchange, dict[str, bytes], None]:
    """The outputs at t_0, sources before the subsystems whose feedthrough outputs need them; a subsystem
    without feedthrough reports before its sources, with zero inputs that its outputs do not depend on."""
    subs = plan.subsystems
    initialised: set[int] = set()
    for round_ in plan.init_rounds:
        sends = {}
        for i in round_:
            s = subs[i]
            ready = all(f.source in initialised for f in s.feeds)
            w0 = input_polynomial(s, 0)[:1] if ready else np.zeros((1, len(s.inputs)))
            sends[s.name] = encode(Kind.INIT, 0, 0, w0, rows=1)
        replies = yield Exchange(sends, tuple(sends))
        for i in round_:
            readers[i].commit(replies[subs[i].name], 0)
        initialised.update(round_)


def _schedule(plan: Plan) -> tuple:
    """What happens at each phase of the schedule, which repeats every lcm of the ratios: (period, the
    subsystems starting a step, those due at its end and their names, the bonds evaluated at its end)."""
    subs = plan.subsystems
    period = math.lcm(*(s.ratio for s in subs))
    starting = [tuple(s for s in subs if phase % s.ratio == 0) for phase in range(period)]
    due = [tuple(s for s in subs if (phase + 1) % s.ratio == 0) for phase in range(period)]
    due_names = [tuple(s.name for s in d) for d in due]
    bonds_due = [tuple((b, bond, bond.components) for b, bond in enumerate(plan.bonds)
                       if (phase + 1) % subs[bond.force_side].ratio == 0
                       and (phase + 1) % subs[bond.motion_side].ratio == 0) for phase in range(period)]
    return period, starting, due, due_names, bonds_due


def _float_rows(command: bytes, n_inputs: int) -> tuple[float, ...]:
    """The values of a one-row command (a ZOH polynomial) as floats."""
    return struct.unpack_from(f"<{n_inputs}d", command, HEADER.size)


def _bond_residual_power(readers: list[OutputReader], sent: list, bond, components, tick: int, step_s: float) -> float:
    """δP of ``bond`` at ``tick`` (paper 002 Eqs. 8–9) from both sides' committed outputs and the input
    polynomials they received; a vector bond's residual power is the dot product: the sum over its components."""
    f_start, f_coefficients = sent[bond.force_side]
    m_start, m_coefficients = sent[bond.motion_side]
    f_row = readers[bond.force_side].newest
    m_row = readers[bond.motion_side].newest
    f_tau, m_tau = (tick - f_start) * step_s, (tick - m_start) * step_s
    delta_p = 0.0
    for force, velocity_input, force_input, velocity in components:
        delta_p += residual_power(f_row[force], evaluate(f_coefficients, velocity_input, f_tau),
                                  evaluate(m_coefficients, force_input, m_tau), m_row[velocity])
    return delta_p
