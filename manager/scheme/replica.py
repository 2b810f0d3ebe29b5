"""Advance a scheme from the replies of every subsystem: the one driver of every bus.

A scheme (``manager.scheme.jacobi``) is deterministic: from the scene and the replies it receives it computes
every command. So every process of a run runs the *same* scheme:

* in-process, one replica holds every subsystem and executes every command itself;
* over Zenoh, each subsystem process holds its own subsystem, executes only its own commands and
  publishes its replies, and takes the other subsystems' replies from the network: a macro-step costs
  one network hop instead of the two of a manager in the loop (manager → subsystem → manager);
* the manager runs the replica that holds no subsystem: it monitors, records and checks, for every
  reply, that the subsystem executed exactly the command the manager's replica computed (CRC-32 in
  the reply header).

A replica that takes replies from the network (``on_drop`` given) checks each one before the scheme
takes it: a well-formed reply header, and the CRC-32 of the command it answers when this replica
computed that command (the manager's replica, every replica of the implicit scheme), else the step the
scheme awaits. A reply that fails is dropped and handed to ``on_drop(name, reason)`` (the bus counts it
with its key) and the replica waits for the next one: a stray, replayed or garbled message does not end
the run, and a subsystem whose replica diverged (different software, different arithmetic) sends only
replies that fail, so the run stalls and the bus's timeout names it with what it dropped.

Two requests stand for many exchanges, where the run is single-rate with zero-order inputs: a subsystem
process's scheme yields one :class:`~zencosim.manager.scheme.lock_step.LockStep` for all its steps, which the
replica runs as the replies arrive (``LockStepRun``: the same commands, replies and screening, without an exchange
per step); the manager's scheme, made ``follower``, yields :class:`~zencosim.manager.scheme.followed_blocks.Follow`
requests and is handed whole macro-steps of queued replies at once (``deliver_batches``), taking a block or giving
it back to the queues to go on step by step.

A :class:`Tap` sees what a replica goes through, in order, one call per exchange: the replies the scheme
took (in simulation order whether they were computed here or came from the network), then the request it
made of them: the status after the macro-step that has just ended, when the scheme reports it, and the
commands. A recorded run taps the in-process replica, on the stepping loop, or the manager's replica that
follows a Zenoh run. :class:`PerMessage` makes a tap of a function of ``(source, channel, message)``.
"""
from __future__ import annotations

from collections import deque
from typing import Callable, Generator, Protocol

from zencosim.manager.scheme.base import Exchange, RunRecord, reply_fault
from zencosim.manager.scheme.followed_blocks import Follow
from zencosim.manager.scheme.lock_step import LockStep, LockStepRun
from zencosim.manager.wire.protocol import command_ref
from zencosim.manager.wire.status import StatusReport


class Tap(Protocol):
    """What sees every message of a replica (see the module text)."""

    def exchange(self, replies: dict[str, bytes] | None, request: Exchange | None) -> None:
        """The replies the scheme took (channels ``<sub>/y``): those the last request awaits, in the order of its
        ``awaits`` (None before the first request); then its next request: ``request.status`` (channel
        ``manager/status``: the step whose message is the next in the run's ``StatusReport`` log; the tap takes
        every one, in order) and ``request.sends`` (channels ``<sub>/commands``); None when the scheme has ended."""


class PerMessage:
    """A :class:`Tap` that hands each message to ``tap(source, channel, message)``; ``status``: the run's
    ``StatusReport``, whose messages it takes one by one."""

    def __init__(self, tap: Callable[[str, str, bytes], None], status: StatusReport | None = None) -> None:
        self.tap = tap
        self.status = status

    def exchange(self, replies: dict[str, bytes] | None, request: Exchange | None) -> None:
        for name, reply in (replies or {}).items():
            self.tap(name, "y", reply)
        if request is not None:
            if request.status is not None:
                self.tap("manager", "status", self.status.take(1).messages)
            for name, command in request.sends.items():
                self.tap(name, "commands", command)


class Replica:
    """One copy of a run's scheme; ``local`` are the subsystem endpoints this process executes."""

    def __init__(self, scheme: Generator[Exchange, dict[str, bytes], RunRecord], names: list[str],
                 local: dict | None = None, publish: Callable[[str, bytes], None] | None = None,
                 tap: Tap | None = None, on_drop: Callable[[str, str], None] | None = None) -> None:
        self.scheme = scheme
        self.local = local or {}
        self.publish = publish
        self.tap = tap
        self.on_drop = on_drop
        self.replies: dict[str, deque[bytes]] = {name: deque() for name in names}
        self.expected: dict[str, deque[int]] = {name: deque() for name in names}
        self.request: Exchange | None = None
        self.result: RunRecord | None = None
        self.steps_done = 0
        # the subsystems the request awaits whose next reply has not passed the screen yet: each reply is looked at
        # once, when it arrives or when a request awaits it, so a step costs a look per reply, not per reply and
        # subsystem awaited (a star of many subsystems: the manager's replica)
        self._missing: set[str] = set()
        self._lock_step: LockStepRun | None = None  # a LockStep request's run (manager.scheme.lock_step)
        self._statements = None  # its subsystem's StatementSteps (subsystems.process.endpoint), where it has them

    @property
    def finished(self) -> bool:
        return self.result is not None

    def waiting_for(self) -> list[str]:
        """Subsystems whose reply the scheme waits for now."""
        if self.request is None:
            return []
        if self._lock_step is not None:
            return self._lock_step.waiting_for()
        if isinstance(self.request, Follow):
            return [name for name, queue in self.replies.items() if not queue]
        return [name for name in self.request.awaits if name in self._missing]

    def start(self) -> None:
        try:
            self.request = next(self.scheme)
        except StopIteration as done:  # a scheme that called its subsystems itself (manager.scheme.direct)
            self.result = done.value
            return
        if not self._runs_many():
            self._execute(None)
            self._await()

    def deliver(self, name: str, reply: bytes) -> None:
        """A reply of subsystem ``name`` from the network."""
        if self._lock_step is not None:
            self._lock_step.deliver(name, reply)
            if self._lock_step.done:
                self._end_lock_step()
            return
        self.replies[name].append(reply)
        if isinstance(self.request, Follow):
            self._follow()
            return
        missing = self._missing
        if name in missing and self._ready(name):
            missing.discard(name)
            if not missing:
                self._advance()

    def deliver_batches(self, batches: list[tuple[str, list[bytes]]]) -> None:
        """Replies from the network, batch after batch (``(subsystem, its replies in order)``): the scheme takes them
        one by one, or whole steps at a time when it asks so (``Follow``), once every batch is queued."""
        for at, (name, replies) in enumerate(batches):
            if isinstance(self.request, Follow):
                for later, more in batches[at:]:
                    self.replies[later].extend(more)
                self._follow()
                return
            for reply in replies:
                self.deliver(name, reply)

    def run(self) -> RunRecord:
        """Run to the end when every subsystem is local (the in-process bus)."""
        self.start()
        if not self.finished:
            raise RuntimeError(f"the scheme waits for {self.waiting_for()}, which no endpoint answers")
        return self.result

    def _execute(self, replies: dict[str, bytes] | None) -> None:
        """Send the request's commands (after the tap has seen ``replies``, what the scheme took to make it)."""
        if self.tap is not None:
            self.tap.exchange(replies, self.request)
        for name, command in self.request.sends.items():
            endpoint = self.local.get(name)
            if endpoint is None:
                if self.on_drop is not None:  # its reply comes from the network: it must carry this reference
                    self.expected[name].append(command_ref(command))
            else:
                reply = endpoint.handle(command)
                if self.publish is not None:
                    self.publish(name, reply)
                self.replies[name].append(reply)

    def _ready(self, name: str) -> bool:
        """Whether subsystem ``name``'s next reply may be taken: there is one, and (from the network, ``on_drop``
        given) the replies at the head of its queue that fail :meth:`fault` are dropped first."""
        queue = self.replies[name]
        if self.on_drop is None or name in self.local:
            return bool(queue)
        while queue:
            reason = self.fault(name, queue[0])
            if reason is None:
                return True
            queue.popleft()
            self.on_drop(name, reason)
        return False

    def _await(self) -> None:
        """Look at the replies the request awaits (every queue, so that waiting_for() names the right ones); hand them
        to the scheme when they are all there."""
        self._missing = {name for name in self.request.awaits if not self._ready(name)}
        if not self._missing:
            self._advance()

    def _advance(self) -> None:
        """Hand the scheme the replies its request awaits, every one there and screened, and go on while the next
        request's are there too (the replies of local subsystems are there at once)."""
        screened = self.on_drop is not None
        while True:
            replies = {name: self.replies[name].popleft() for name in self.request.awaits}
            if screened:
                for name in replies:
                    if self.expected[name]:
                        self.expected[name].popleft()
            try:
                self.request = self.scheme.send(replies)
            except StopIteration as done:
                self.result = done.value
                self.request = None
                if self.tap is not None:
                    self.tap.exchange(replies, None)
                return
            self.steps_done += 1
            if self._runs_many():
                return
            self._execute(replies)
            self._missing = {name for name in self.request.awaits if not self._ready(name)}
            if self._missing:
                return

    def _runs_many(self) -> bool:
        """Run the request when it stands for many exchanges (``LockStep``, ``Follow``: see the module text); whether
        it did."""
        if isinstance(self.request, LockStep):
            self._start_lock_step()
        elif isinstance(self.request, Follow):
            self._follow()
        else:
            return False
        return True

    def _follow(self) -> None:
        """While the scheme asks for whole steps (``Follow``) and every subsystem has a reply queued: hand it the
        replies of as many steps as every queue holds. A block it does not take goes back to the queues, and the
        scheme, which then exchanges step by step, gets its replies as any request's."""
        queues = self.replies
        while isinstance(self.request, Follow):
            tick = self.request.tick
            count = min(min(map(len, queues.values())), self.request.end - tick)
            if count == 0:
                return
            block = {name: [queue.popleft() for _ in range(count)] for name, queue in queues.items()}
            try:
                self.request = self.scheme.send(block)
            except StopIteration as done:
                self.result = done.value
                self.request = None
                self.steps_done += count
                return
            if not isinstance(self.request, Follow):
                for name, replies in block.items():
                    queues[name].extendleft(reversed(replies))
                self._execute(None)
                self._await()
                return
            self.steps_done += self.request.tick - tick

    def _start_lock_step(self) -> None:
        """Run the scheme's :class:`LockStep` request: its one local subsystem's steps, the replies that came early
        handed over first."""
        request = self.request
        endpoint = self.local[request.own.name]
        self._statements = endpoint.zero_order_steps()  # its step as statements, where it has them
        answer = (self._statements.answer if self._statements is not None
                  else lambda _, command: endpoint.handle(command))
        self._lock_step = run = LockStepRun(request, answer, self.publish, self.on_drop)
        run.start()
        for name, queue in self.replies.items():
            while queue and not run.done:
                run.deliver(name, queue.popleft())
        if run.done:
            self._end_lock_step()

    def _end_lock_step(self) -> None:
        """The lock step's last replies are in: the scheme ends."""
        run, self._lock_step = self._lock_step, None
        self.steps_done += run.tick - run.request.first
        if self._statements is not None:  # the subsystem takes the state its statements left
            self._statements.end(run.tick)
        try:
            self.request = self.scheme.send(None)
        except StopIteration as done:
            self.result = done.value
            self.request = None
            return
        raise RuntimeError("a scheme goes on after a LockStep request; it must end")

    def fault(self, name: str, reply: bytes) -> str | None:
        """Why the scheme must not take ``reply``, the next of subsystem ``name`` from the network (None: it may)."""
        expected = self.expected[name]
        return reply_fault(reply, name, expected[0] if expected else None, self.request.step)
