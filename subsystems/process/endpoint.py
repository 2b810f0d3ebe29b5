"""The subsystem side of the wire protocol: decode a command, act on the subsystem, encode the reply.

The same endpoint serves a subsystem process (called from its Zenoh subscriber) and the in-process implicit
scheme (called directly), on identical bytes; the in-process Jacobi scheme calls the subsystems without bytes
(``manager.bus.inproc.DirectCalls``), naming a failure as ``failure_reason`` does.
"""
from __future__ import annotations

import struct
from collections.abc import Callable

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
from zencosim.subsystems.straight_line import StepText, body_lines, define
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

    def zero_order_steps(self) -> StatementSteps | None:
        """The subsystem's zero-order STEPs answered by its step's statements (:class:`StatementSteps`), or None where
        it has none (``Subsystem.step_text``)."""
        text = self.subsystem.step_text(self.ratio * self.base_step_ns, "", f"tick * {self.base_step_ns}")
        if text is None or len(text.outputs) != len(self.subsystem.outputs):
            return None
        return StatementSteps(self, text)

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


class StatementSteps:
    """A subsystem's zero-order STEP commands answered by its step as statements over floats (``Subsystem.step_text``:
    a small linear model's straight-line step, a co-simulation FMU's calls) in one generated function, its state kept
    as floats from call to call: the reply ``SubsystemEndpoint.handle`` gives, byte for byte (the same statements
    ``advance_values`` runs, the values read from the command's bytes, its ``command_ref`` as the reference; a
    failure answered with the same ERROR). For a subsystem process in lock step (``manager.scheme.lock_step``),
    which calls :meth:`answer` once a step and :meth:`end` when its steps are done."""

    def __init__(self, endpoint: SubsystemEndpoint, text: StepText) -> None:
        self.endpoint = endpoint
        self.state = endpoint.subsystem.z.tolist()
        self.inputs_at_end: list[float] | None = None  # None: no step taken
        self._step: Callable = define(_answer_text(endpoint, text), "answer", "<zero-order step>", {
            **text.namespace, "HEADER": HEADER, "inputs_of": endpoint._unpack_inputs, "command_ref": command_ref,
            "outputs_of": endpoint._pack_outputs})

    def answer(self, tick: int, command: bytes) -> bytes:
        """The reply to the zero-order STEP ``command`` of step ``tick`` (a valid one: its header as the scheme
        writes it)."""
        try:
            reply, self.state, self.inputs_at_end = self._step(tick, command, self.state)
            return reply
        except (Exception, SystemExit, KeyboardInterrupt) as error:  # as handle answers a failing command
            reason = failure_reason(error)
            if reason is None:
                raise
            return encode_error(tick, tick * self.endpoint.base_step_ns, reason, command_ref(command))

    def end(self, tick: int) -> None:
        """The steps are done at base step ``tick``: the subsystem takes the state they left (``took_steps``)."""
        if self.inputs_at_end is not None:
            self.endpoint.subsystem.took_steps(tick * self.endpoint.base_step_ns, self.state, self.inputs_at_end)


def _answer_text(endpoint: SubsystemEndpoint, text: StepText) -> str:
    """The source of ``answer(tick, command, state) -> (reply, state, inputs at the end)``: the command's input values
    as ``_zero_order_step`` reads them, the step's statements, the OUTPUT reply as it packs it."""
    due = f"tick + {endpoint.ratio}"
    lines = ["def answer(tick, command, state):", *body_lines(text, "state", f"inputs_of(command, {HEADER.size})")]
    lines.append(f"    return (HEADER.pack({VERSION}, {int(Kind.OUTPUT)}, 0, {len(text.outputs)}, {due}, "
                 f"({due}) * {endpoint.base_step_ns}, command_ref(command))"
                 f" + outputs_of({', '.join(text.outputs)}), [{', '.join(text.new_state)}], "
                 f"[{', '.join(text.inputs_at_end)}])")
    return "\n".join(lines)
