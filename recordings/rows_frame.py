"""ROWS frames: a generated loop's rows (``manager.scheme.tapped.RowsBlock``), from the recorder's tap to its processes.

A recorded in-process run whose macro-steps run as one generated loop (``manager.scheme.compiled``: single-rate
Jacobi, zero-order inputs) hands its tap the rows the loop makes anyway — every subsystem's outputs, every bond's δP
and δE — with each step's release and completion times; the recorder process and the live view build from them the
messages a replica's tap would have handed over, in the same order (:func:`rows_messages`): a request's commands are
the outputs of the row before it (the sources' newest outputs, each input from ``zero_order_sources``), each reply's
outputs its own row, each status the residuals and times of its step's row (``manager.wire.status.status_messages``).
So a recorded run's stepping loop is the unrecorded one's; its tap copies nothing but the frame (issue 26).

Layout (little endian): ``ROWS_HEAD`` (bytes of the JSON that follows, rows n, requests r, flags, the first request's
tick, the release of step 0 and the offset from the steps' clock to the wall clock [ns]), the JSON (subsystem
names, base step [ns], each subsystem's number of outputs and its inputs' sources, the number of bonds: the same in
every frame of a run), the n rows (f64, every subsystem's outputs, then δP and δE of every bond), then the n
release and the n completion times (i64). Row 0 is carried: the step before the first request (at the run's start,
the outputs at t_0 and nothing else); rows 1 … answer requests 0 ….
"""
from __future__ import annotations

import json
import struct

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scheme.tapped import RowsBlock, SubsystemSteps, rows_replies, rows_status_steps
from zencosim.manager.wire.status import status_messages
from zencosim.recordings.steps_frame import block_messages

ROWS_HEAD = struct.Struct("<IIIIqqq")
ANSWERED, END_STATUS, STATUS = 1, 2, 4  # flags: the last request's replies are in; the run's last status; statuses


def rows_about(plan: Plan) -> bytes:
    """The JSON of every ROWS frame of a run of ``plan``."""
    return json.dumps({"names": [s.name for s in plan.subsystems], "base_step_ns": plan.base_step_ns,
                       "outputs": [len(s.outputs) for s in plan.subsystems],
                       "sources": [s.zero_order_sources for s in plan.subsystems],
                       "bonds": len(plan.bonds)}).encode()


def rows_frame(block: RowsBlock, about: bytes, clock_offset_ns: int) -> bytes:
    """The ROWS frame of ``block`` (``about``: :func:`rows_about`; ``clock_offset_ns``: wall clock minus the steps'
    clock, ``perf_counter_ns``)."""
    flags = ANSWERED * block.answered | END_STATUS * block.end_status | STATUS * block.status
    n = sum(len(rows) for rows in block.rows)
    return b"".join([ROWS_HEAD.pack(len(about), n, block.requests, flags, block.first, block.start_ns,
                                    clock_offset_ns), about, *block.rows, *block.released, *block.completed])


def rows_messages(frame: bytes, index: dict[tuple[str, str], int], status: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bytes]:
    """The messages of a ROWS frame in the run's order, as ``steps_frame.steps_messages`` returns a STEPS frame's; a
    frame that does not hold what its head says raises ValueError."""
    try:
        about_bytes, n, requests, flags, first, start_ns, offset_ns = ROWS_HEAD.unpack_from(frame)
        at = ROWS_HEAD.size
        about = json.loads(frame[at:at + about_bytes])
        at += about_bytes
        names, outputs, n_bonds = about["names"], about["outputs"], int(about["bonds"])
        starts = np.cumsum([0, *outputs])
        width = int(starts[-1]) + 2 * n_bonds
        rows = np.frombuffer(frame, dtype="<f8", count=n * width, offset=at).reshape(n, width)
        released = np.frombuffer(frame, dtype="<i8", count=n, offset=at + 8 * n * width)
        completed = np.frombuffer(frame, dtype="<i8", count=n, offset=at + 8 * n * (width + 1))
        answered, end_status = bool(flags & ANSWERED), bool(flags & END_STATUS)
        if at + 8 * n * (width + 2) != len(frame) or not 1 <= requests <= n or (answered and requests != n - 1) \
                or (end_status and not answered):
            raise ValueError("its parts do not add up to its length")
        replies = rows_replies(requests, answered)
        ticks = first + np.arange(requests, dtype=np.int64)
        subsystems = [SubsystemSteps(ticks, rows[:requests, [int(starts[source]) + output for source, output in fed]],
                                     1, ticks[:replies] + 1, rows[1:1 + replies, starts[i]:starts[i + 1]])
                      for i, fed in enumerate(about["sources"])]
        steps = rows_status_steps(first, requests, end_status, bool(flags & STATUS))
        carrying = np.arange(steps.start, steps.stop) - first  # a status's step is its row's
        statuses = status_messages(rows[carrying, int(starts[-1]):], first + carrying, released[carrying],
                                   completed[carrying], None, start_ns, int(about["base_step_ns"]))
        everyone = tuple(range(len(names)))
        layouts = [((), bool(flags & STATUS) and first > 0, everyone), (everyone, bool(flags & STATUS), everyone),
                   (everyone, end_status, ())]
        order = np.ones(requests + answered, dtype=np.intp)
        order[0], order[requests:] = 0, 2
        return block_messages(names, int(about["base_step_ns"]), layouts, order, subsystems, statuses,
                              completed[carrying] + offset_ns, index, status)
    except (struct.error, ValueError, KeyError, IndexError, TypeError) as error:
        raise ValueError(f"a ROWS frame that does not hold what its head says ({error})") from None
