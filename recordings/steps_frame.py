"""STEPS frames: a block of a direct (in-process) run's exchanges as arrays, from the recorder's tap to its processes.

A direct run hands its tap blocks of arrays, not messages (``manager.scheme.tapped.StepsBlock``); the recorder
sends each as one STEPS frame, and the recorder process and the live view build from it the wire messages a
replica's tap would have handed over, in the same order (:func:`steps_messages`), which they then take as a
BATCH frame's (``recordings.recorder_process``). So the stepping loop encodes no message of a recorded in-process
run; the other processes, on the other core, do.

A block answers its own commands (``StepsBlock``): the k-th reply of a subsystem answers its k-th command, and
carries that command's CRC-32 as its reference, which is computed here.

Layout (little endian): ``STEPS_HEAD`` (bytes of the JSON that follows, statuses m, bytes of the statuses,
exchanges e), the JSON (subsystem names, base step [ns], the layouts of the exchanges, per subsystem how many
commands of how many rows and values and how many replies of how many outputs), m wall-clock times (i64), the m
statuses (all of one size, from the status log: ``manager.wire.status``), e layout numbers (u32), then per
subsystem its commands' ticks (i64) and values (f64), its replies' steps (i64) and outputs (f64).
"""
from __future__ import annotations

import json
import marshal
import struct

import numpy as np

from zencosim.manager.scheme.tapped import PendingSteps, StepsBlock, StepsSchedule, SubsystemSteps, TakenSteps
from zencosim.manager.wire.protocol import Kind, command_refs, encode_rows
from zencosim.manager.wire.status import Statuses, StatusReport
from zencosim.recordings.encoding import write_rows

STEPS_HEAD = struct.Struct("<IIII")


def steps_frame(block: StepsBlock, statuses: Statuses) -> bytes:
    """The STEPS frame of ``block`` with the ``statuses`` its exchanges report (taken from the status log)."""
    about = {"names": block.names, "base_step_ns": block.base_step_ns,
             "layouts": [[list(replying), status, list(commanded)] for replying, status, commanded in block.layouts],
             "subsystems": [[len(s.ticks), s.rows, s.polynomials.shape[1], len(s.steps), s.outputs.shape[1]]
                            for s in block.subsystems]}
    text = json.dumps(about).encode()
    parts = [STEPS_HEAD.pack(len(text), len(statuses.steps), len(statuses.messages), len(block.order)), text,
             statuses.stamps.astype("<i8").tobytes(), statuses.messages, block.order.astype("<u4").tobytes()]
    for s in block.subsystems:
        parts += [s.ticks.astype("<i8").tobytes(), s.polynomials.astype("<f8").tobytes(),
                  s.steps.astype("<i8").tobytes(), s.outputs.astype("<f8").tobytes()]
    return b"".join(parts)


def pending_payload(pending: PendingSteps, n_residuals: int, log: tuple[int | None, list[float], list[int]]) -> bytes:
    """A PENDING frame: requests a direct run took since it last handed something over (``TakenSteps.hand_over``),
    and what its status log took since then (``log``: the release of step 0 once known, residuals and times; each
    step's ``n_residuals``), as ``marshal`` writes them (one C call on the stepping loop)."""
    return marshal.dumps((tuple(pending.schedule), pending.ticks, pending.shapes, pending.commands, pending.outputs,
                          n_residuals, log))


def pending_steps(payloads: list[bytes]) -> bytes | None:
    """The STEPS frame of the block the run would have handed over where it sent the last of the PENDING frames
    ``payloads``, those since its last block (``TakenSteps.pending_block``), with the statuses its log held then;
    None where they hold no request."""
    parts = [marshal.loads(payload) for payload in payloads]
    schedule = StepsSchedule(*parts[0][0])
    block = TakenSteps.pending_block([PendingSteps(schedule, *part[1:5]) for part in parts])
    if block is None:
        return None
    log = (parts[-1][6][0], [r for part in parts for r in part[6][1]], [t for part in parts for t in part[6][2]])
    return steps_frame(block, StatusReport.from_log(parts[0][5], schedule.base_step_ns, log).take(block.statuses))


def steps_messages(frame: bytes, index: dict[tuple[str, str], int], status: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bytes]:
    """The messages of a STEPS frame in the run's order: (channel index of each, size of each, the statuses'
    wall-clock times, the messages joined), as ``recorder_process.split_batch`` gives a BATCH frame's. ``index``:
    the channel index of each (subsystem, ``"y"`` or ``"commands"``); ``status``: the status channel's. A frame that
    does not hold what its head says raises ValueError."""
    try:
        text_bytes, m, statuses_bytes, e = STEPS_HEAD.unpack_from(frame)
        at = STEPS_HEAD.size
        about = json.loads(frame[at:at + text_bytes])
        at += text_bytes
        stamps = np.frombuffer(frame, dtype="<i8", count=m, offset=at)
        at += 8 * m
        statuses = np.frombuffer(frame, dtype=np.uint8, count=statuses_bytes, offset=at)
        at += statuses_bytes
        order = np.frombuffer(frame, dtype="<u4", count=e, offset=at).astype(np.intp)
        at += 4 * e
        subsystems = []
        for commanded, rows, width, answered, n_outputs in about["subsystems"]:
            ticks = np.frombuffer(frame, dtype="<i8", count=commanded, offset=at)
            values = np.frombuffer(frame, dtype="<f8", count=commanded * width, offset=at + 8 * commanded)
            at += 8 * commanded * (1 + width)
            steps = np.frombuffer(frame, dtype="<i8", count=answered, offset=at)
            outputs = np.frombuffer(frame, dtype="<f8", count=answered * n_outputs, offset=at + 8 * answered)
            at += answered * (8 + 8 * n_outputs)
            subsystems.append(SubsystemSteps(ticks, values.reshape(commanded, width), rows, steps,
                                             outputs.reshape(answered, n_outputs)))
        if at != len(frame) or (statuses_bytes % m if m else statuses_bytes):
            raise ValueError("its parts do not add up to its length")
        layouts = [(tuple(replying), follows, tuple(commanded)) for replying, follows, commanded in about["layouts"]]
        return block_messages(about["names"], int(about["base_step_ns"]), layouts, order, subsystems,
                              statuses.reshape(m, statuses_bytes // m) if m else statuses.reshape(0, 0), stamps,
                              index, status)
    except (struct.error, ValueError, KeyError, IndexError, TypeError) as error:
        raise ValueError(f"a STEPS frame that does not hold what its head says ({error})") from None


def block_messages(names: list[str], base_step_ns: int, layouts: list[tuple[tuple[int, ...], bool, tuple[int, ...]]],
                   order: np.ndarray, subsystems: list[SubsystemSteps], statuses: np.ndarray, stamps: np.ndarray,
                   index: dict[tuple[str, str], int], status: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, bytes]:
    """The messages of a block of exchanges (``StepsBlock``'s parts, with its ``statuses``: one row of bytes each,
    and their wall-clock ``stamps``) in the run's order, as :func:`steps_messages` returns them. ValueError (or
    IndexError, KeyError) where the exchanges take more messages than the parts hold.

    Built with numpy, not message by message: each subsystem's replies and commands are one array of records each
    (a stream), the statuses another; the exchanges' layouts name each message's stream in turn, and a stream's
    k-th message is its k-th record, written where it goes (``encoding.write_rows``)."""
    streams: list[np.ndarray] = []  # per subsystem its replies, then its commands (uint8 rows); the statuses last
    for s in subsystems:
        answered = len(s.steps)
        sent = encode_rows(Kind.STEP, s.ticks, base_step_ns, s.polynomials, s.rows, 0)
        if answered > len(sent):
            raise ValueError(f"{answered} replies to {len(sent)} commands")
        references = command_refs(sent[:answered])  # each reply's reference: its command's CRC-32
        streams += [encode_rows(Kind.OUTPUT, s.steps, base_step_ns, s.outputs, 0, references), sent]
    streams.append(statuses)
    layouts_entries = [[(2 * i, index[names[i], "y"]) for i in replying]
                       + ([(2 * len(names), status)] if follows else [])
                       + [(2 * i + 1, index[names[i], "commands"]) for i in commanded]
                       for replying, follows, commanded in layouts]
    # each message's stream and channel: the entries of its exchange's layout, exchange after exchange
    entries = np.array([entry for layout in layouts_entries for entry in layout], dtype=np.int64).reshape(-1, 2)
    lengths = np.array([len(layout) for layout in layouts_entries], dtype=np.int64)
    taken = lengths[order]
    entry = (np.repeat((np.cumsum(lengths) - lengths)[order] - (np.cumsum(taken) - taken), taken)
             + np.arange(int(taken.sum())))
    stream, channels = entries[entry, 0], entries[entry, 1]
    sizes = np.array([rows.shape[1] for rows in streams], dtype=np.int64)[stream]
    offsets = np.cumsum(sizes) - sizes
    joined = np.empty(int(sizes.sum()), dtype=np.uint8)
    for k, rows in enumerate(streams):
        where = offsets[stream == k]
        if len(where) > len(rows):
            raise ValueError(f"its exchanges take {len(where)} messages of a part holding {len(rows)}")
        if len(where):
            write_rows(joined, where, rows[:len(where)])
    return channels.astype(np.uint8), sizes, stamps, joined.tobytes()
