"""The subsystem side of the wire protocol: decode a command, act on the subsystem, encode the reply.

The same endpoint serves a subsystem process (called from its Zenoh subscriber) and the in-process implicit
scheme (called directly), on identical bytes; the in-process Jacobi scheme calls the subsystems without bytes
(``manager.bus.inproc.DirectCalls``), naming a failure as ``failure_reason`` does.
"""
from __future__ import annotations

import struct

from zencosim.manager.bus.signals import raised_by_code
from zencosim.manager.wire.protocol import (
    HEADER,
    VERSION,
    Kind,
    ProtocolError,
    command_ref,
    decode,
    encode,
    encode_error,
)
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.subsystem import SavedState, Subsystem


def failure_reason(error: BaseException) -> str | None:
    """Why a command failed, as its ERROR reply says: an exception, a model that called ``sys.exit()`` (its failure,
    not the end of the run) or raised KeyboardInterrupt itself (``manager.bus.signals.raised_by_code``); None for
    a KeyboardInterrupt of the user's (Ctrl-C, SIGTERM), which interrupts the run."""
    if isinstance(error, SystemExit):
        return f"the model exited (SystemExit {error.code})"
    if isinstance(error, KeyboardInterrupt):
        return "the model raised KeyboardInterrupt (no SIGINT or SIGTERM was received)" if raised_by_code() else None
    return f"{type(error).__name__}: {error}"


class SubsystemEndpoint:
    """Answers manager commands for one subsystem that communicates every ``ratio`` base steps."""

    def __init__(self, subsystem: Subsystem, ratio: int, base_step_ns: int) -> None:
        self.subsystem = subsystem
        self.ratio = ratio
        self.base_step_ns = base_step_ns
        self.n_inputs = len(subsystem.inputs)
        self.saved: tuple[int, SavedState] | None = None  # (step, state): SAVE replaces the previous one
        self._zero_order_size = HEADER.size + 8 * self.n_inputs  # a STEP with one row of inputs: its bytes
        self._unpack_inputs = struct.Struct(f"<{self.n_inputs}d").unpack_from
        self._pack_outputs = struct.Struct(f"<{len(subsystem.outputs)}d").pack

    def handle(self, data: bytes) -> bytes:
        """One command in, one reply out (carrying the command's reference); a failing command is
        answered with an ERROR message (:func:`failure_reason`); a KeyboardInterrupt of the user's goes on."""
        step, time_ns, ref = -1, -1, command_ref(data)
        try:
            if len(data) == self._zero_order_size:  # perhaps a zero-order STEP: its values as floats, no array
                version, kind, rows, count, step, time_ns, span = HEADER.unpack_from(data)
                if version == VERSION and kind == Kind.STEP and rows == 1 and count == self.n_inputs:
                    return self._zero_order_step(step, time_ns, self._unpack_inputs(data, HEADER.size), ref, span)
                step, time_ns = -1, -1
            message = decode(data, "manager")
            step, time_ns = message.step, message.time_ns
            return self._dispatch(message, ref)
        except (Exception, SystemExit, KeyboardInterrupt) as error:  # the manager names the subsystem, stops the run
            reason = failure_reason(error)
            if reason is None:
                raise
            return encode_error(step, time_ns, reason, ref)

    def _zero_order_step(self, step: int, time_ns: int, inputs: tuple[float, ...], ref: int, span: int) -> bytes:
        """A STEP's reply as ``_dispatch`` gives it, its one row of inputs taken as floats
        (``Subsystem.advance_values``): the same outputs, the same bytes."""
        span = span or self.ratio  # as _dispatch reads a STEP's length
        due, t1 = step + span, time_ns + span * self.base_step_ns
        y = self.subsystem.advance_values(time_ns, t1, list(inputs))
        if type(y) is not list:
            return encode(Kind.OUTPUT, due, t1, y, ref=ref)
        return HEADER.pack(VERSION, Kind.OUTPUT, 0, len(y), due, t1, ref) + self._pack_outputs(*y)

    def _inputs(self, message) -> InputPolynomial:
        rows = message.rows
        if rows < 1 or message.values.size != rows * self.n_inputs:
            raise ProtocolError(f"subsystem {self.subsystem.name}: expected {self.n_inputs} inputs per row, "
                                f"got {message.values.size} values in {rows} rows")
        return InputPolynomial(message.values.reshape(rows, self.n_inputs))

    def _dispatch(self, message, ref: int) -> bytes:
        sub = self.subsystem
        kind = message.kind
        if kind == Kind.STEP:  # its length: the header's last field in base steps (0: the communication step)
            span = message.ref or self.ratio
            t1 = message.time_ns + span * self.base_step_ns
            y = sub.advance(message.time_ns, t1, self._inputs(message))
            return encode(Kind.OUTPUT, message.step + span, t1, y, ref=ref)
        if kind == Kind.INIT:
            if message.time_ns != sub.t_ns:
                raise ProtocolError(f"subsystem {sub.name}: INIT at t = {message.time_ns} ns, but it is at {sub.t_ns} ns")
            return encode(Kind.OUTPUT, message.step, message.time_ns, sub.output_values(self._inputs(message).at(0.0)),
                          ref=ref)
        if kind == Kind.SAVE:
            self.saved = (message.step, sub.save())
            return encode(Kind.ACK, message.step, sub.t_ns, ref=ref)
        if kind == Kind.RESTORE:
            if self.saved is None or self.saved[0] != message.step:
                raise ProtocolError(f"subsystem {sub.name}: no state saved at step {message.step}")
            sub.restore(self.saved[1])
            return encode(Kind.ACK, message.step, sub.t_ns, ref=ref)
        if kind == Kind.PROJECT:
            if message.time_ns != sub.t_ns:
                raise ProtocolError(f"subsystem {sub.name}: PROJECT at t = {message.time_ns} ns, but it is at {sub.t_ns} ns")
            return encode(Kind.OUTPUT, message.step, message.time_ns, sub.project(message.values), ref=ref)
        raise ProtocolError(f"subsystem {sub.name}: cannot handle a {kind.name} message")

