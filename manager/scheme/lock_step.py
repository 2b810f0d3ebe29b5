"""A subsystem process's macro-steps in lock step with its sources, without the scheme's loop (issue 26).

Over Zenoh each subsystem process runs a replica of the Jacobi scheme (``manager.scheme.replica``) that computes
its own commands from its sources' replies. When the run is single-rate, the process's subsystem takes zero-order
inputs each fed once (``SubsystemPlan.zero_order_sources``) and nothing else is asked of the process's replica (no
corrector, no status, no progress: it evaluates no bond), a macro-step of that replica is: once every source's reply
for step j is in, the STEP command for step j is the header and its sources' output bytes as they arrived (paper
000 §2.1, ZOH), the step is released (paced in a real-time run), the subsystem answers it, and the reply is
published. The scheme (``manager.scheme.jacobi``) then yields one :class:`LockStep` request for all its macro-steps,
and the replica hands the replies to a :class:`LockStepRun`, which does exactly that per step: the same commands
byte for byte, the same release times recorded, the same replies, the same screening of replies from the network
(``manager.scheme.base.reply_fault``, then ``check_output``, which names a subsystem's failure), without the
layers of a generic exchange. When the last step's replies are in, the scheme returns its record: the release
times the process reports (``manager.bus.timing``); its trajectories hold the outputs at t_0 only, its residuals
none (the manager's replica records the run).
"""
from __future__ import annotations

import struct
from collections import deque
from dataclasses import dataclass
from typing import Callable

from zencosim.manager.plan.run_plan import SubsystemPlan
from zencosim.manager.scheme.base import check_output, reply_fault
from zencosim.manager.wire.protocol import HEADER, VERSION, Kind

_HEAD = struct.Struct("<8sq")  # an OUTPUT's version, kind, rows, count as bytes, and its step


@dataclass(frozen=True)
class LockStep:
    """The request for macro-steps ``first`` … ``end - 1`` in lock step (see the module text): subsystem ``own``
    answers each step's command; ``tracked`` are the subsystems whose replies each step awaits (``own`` and its
    sources), ``newest`` their replies for step ``first``; the command's values are the byte ranges ``segments``
    (``(subsystem, start, end)``) of those replies, in input order; ``release(tick)`` releases a step and records it
    (``manager.scheme.pacing.Releases``). The scheme is sent None when the last step's replies are in."""

    own: SubsystemPlan
    tracked: tuple[SubsystemPlan, ...]
    newest: dict[str, bytes]
    segments: tuple[tuple[str, int, int], ...]
    first: int
    end: int
    base_step_ns: int
    release: Callable[[int], int]


class LockStepRun:
    """Runs a :class:`LockStep` as the replies arrive; ``answer(tick, command)``: the own subsystem's reply to its
    command of step ``tick`` (``subsystems.process.endpoint``: ``StatementSteps.answer``, or its ``handle``),
    ``publish(name, reply)``: where its replies go, ``on_drop(name, reason)``: a reply from the network that is
    not taken (``manager.scheme.replica``)."""

    def __init__(self, request: LockStep, answer: Callable[[int, bytes], bytes],
                 publish: Callable[[str, bytes], None] | None, on_drop: Callable[[str, str], None]) -> None:
        self.request = request
        self.answer, self.publish, self.on_drop = answer, publish, on_drop
        self.tick = request.first
        self.newest = dict(request.newest)
        self.later: dict[str, deque[bytes]] = {s.name: deque() for s in request.tracked}
        # each tracked subsystem's OUTPUT: its size and the first 8 bytes of its header (version, kind, rows, count)
        self.size = {s.name: HEADER.size + 8 * len(s.outputs) for s in request.tracked}
        self.prefix = {s.name: HEADER.pack(VERSION, Kind.OUTPUT, 0, len(s.outputs), 0, 0, 0)[:8]
                       for s in request.tracked}
        self.sources = tuple(s.name for s in request.tracked if s is not request.own)
        self.missing: set[str] = set()
        self.unusual: set[str] = set()  # tracked subsystems whose reply for the current step is no plain OUTPUT
        self.early = 0  # replies in ``later``
        self.done = request.first >= request.end
        self._command_head = (VERSION, int(Kind.STEP), 1, len(request.own.inputs))  # a STEP's header, up to its step

    def waiting_for(self) -> list[str]:
        """The subsystems whose reply for the current step is not in yet."""
        return [name for name in self.sources if name in self.missing]

    def start(self) -> None:
        """Step while the replies are there (at the start, every source's reply for the first step is)."""
        if not self.done:
            self._run()

    def deliver(self, name: str, reply: bytes) -> None:
        """A reply of source ``name`` from the network."""
        missing = self.missing
        if name in missing and not self.later[name]:
            if self._accept(name, reply):
                missing.discard(name)
                if not missing:
                    self._run()
        else:
            self.later[name].append(reply)
            self.early += 1

    def _accept(self, name: str, reply: bytes) -> bool:
        """Take ``reply`` as ``name``'s for the current step when it may be taken (True; one that is no OUTPUT for
        the step, an ERROR, is noted: ``_commit`` raises its named error), drop it with its reason when it may not
        (False)."""
        if len(reply) != self.size[name] or _HEAD.unpack_from(reply) != (self.prefix[name], self.tick):
            reason = reply_fault(reply, name, None, self.tick)
            if reason is not None:
                self.on_drop(name, reason)
                return False
            self.unusual.add(name)
        self.newest[name] = reply
        return True

    def _take(self, name: str) -> bool:
        """Whether ``name``'s reply for the current step is in: the replies that came early, screened in order."""
        later = self.later[name]
        while later:
            self.early -= 1
            if self._accept(name, later.popleft()):
                return True
        return False

    def _commit(self) -> None:
        """Every tracked reply for the current step is in: as the scheme commits them, in plan order, the first that
        is no OUTPUT for the step raises its named error (``check_output``: a subsystem's failure, an ERROR)."""
        for s in self.request.tracked:
            if s.name in self.unusual:
                check_output(self.newest[s.name], s, self.tick)
        self.unusual.clear()

    def _run(self) -> None:
        """Every step whose tracked replies are in: their commit, the step's command, its release, the own
        subsystem's reply."""
        request, newest, sources = self.request, self.newest, self.sources
        own = request.own.name
        segments, header, head, base = request.segments, HEADER.pack, self._command_head, request.base_step_ns
        own_size, own_prefix = self.size[own], self.prefix[own]
        while True:
            if self.unusual:
                self._commit()
            tick = self.tick
            if tick >= request.end:
                self.done = True
                return
            command = header(*head, tick, tick * base, 0) + b"".join([newest[name][start:end]
                                                                      for name, start, end in segments])
            request.release(tick)
            reply = self.answer(tick, command)
            if self.publish is not None:
                self.publish(own, reply)
            self.tick = tick = tick + 1
            # its own replies are not screened (the scheme takes them as they are): one that is no OUTPUT is noted
            if len(reply) != own_size or _HEAD.unpack_from(reply) != (own_prefix, tick):
                self.unusual.add(own)
            newest[own] = reply
            # the sources' replies for the next step: none is in unless one came early
            self.missing = {name for name in sources if not self._take(name)} if self.early else set(sources)
            if self.missing:
                return
