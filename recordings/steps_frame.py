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
import struct

import numpy as np

from zencosim.manager.scheme.tapped import StepsBlock
from zencosim.manager.wire.protocol import HEADER_DTYPE, VERSION, Kind, command_ref
from zencosim.manager.wire.status import Statuses

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
        statuses = frame[at:at + statuses_bytes]
        at += statuses_bytes
        order = np.frombuffer(frame, dtype="<u4", count=e, offset=at).tolist()
        at += 4 * e
        base = int(about["base_step_ns"])
        commands, replies = [], []
        for commanded, rows, width, answered, n_outputs in about["subsystems"]:
            ticks = np.frombuffer(frame, dtype="<i8", count=commanded, offset=at)
            values = np.frombuffer(frame, dtype="<f8", count=commanded * width, offset=at + 8 * commanded)
            at += 8 * commanded * (1 + width)
            steps = np.frombuffer(frame, dtype="<i8", count=answered, offset=at)
            outputs = np.frombuffer(frame, dtype="<f8", count=answered * n_outputs, offset=at + 8 * answered)
            at += answered * (8 + 8 * n_outputs)
            sent = _messages(Kind.STEP, ticks, base, values.reshape(commanded, width), rows, 0)
            if answered > commanded:
                raise ValueError(f"{answered} replies to {commanded} commands")
            references = np.array([command_ref(command) for command in sent[:answered]], dtype=np.uint32)
            commands.append(iter(sent))
            replies.append(iter(_messages(Kind.OUTPUT, steps, base, outputs.reshape(answered, n_outputs), 0,
                                          references)))
        if at != len(frame) or (statuses_bytes % m if m else statuses_bytes):
            raise ValueError("its parts do not add up to its length")
        size = statuses_bytes // m if m else 0
        each_status = iter([statuses[start:start + size] for start in range(0, statuses_bytes, size or 1)])
        names = about["names"]
        layouts = [([index[names[i], "y"] for i in replying], status_follows,
                    [index[names[i], "commands"] for i in commanded], replying, commanded)
                   for replying, status_follows, commanded in about["layouts"]]
        channels, ordered = [], []
        for number in order:
            reply_channels, status_follows, command_channels, replying, commanded = layouts[number]
            channels += reply_channels
            ordered += [next(replies[i]) for i in replying]
            if status_follows:
                channels.append(status)
                ordered.append(next(each_status))
            channels += command_channels
            ordered += [next(commands[i]) for i in commanded]
    except (struct.error, ValueError, KeyError, IndexError, TypeError, StopIteration) as error:
        raise ValueError(f"a STEPS frame that does not hold what its head says ({error})") from None
    return (np.array(channels, dtype=np.uint8), np.fromiter(map(len, ordered), dtype=np.int64, count=len(ordered)),
            stamps, b"".join(ordered))


def _messages(kind: Kind, steps: np.ndarray, base_step_ns: int, values: np.ndarray, rows: int,
              references: np.ndarray | int) -> list[bytes]:
    """Messages of one kind and shape, a row of ``values`` each, as ``manager.wire.protocol.encode`` writes them."""
    records = np.zeros(len(steps), dtype=[("header", HEADER_DTYPE), ("values", "<f8", (values.shape[1],))])
    header = records["header"]
    header["version"], header["kind"], header["rows"], header["count"] = VERSION, kind, rows, values.shape[1]
    header["step"], header["time_ns"], header["ref"] = steps, steps * base_step_ns, references
    records["values"] = values
    data, size = records.tobytes(), records.dtype.itemsize
    return [data[at:at + size] for at in range(0, len(data), size)]
