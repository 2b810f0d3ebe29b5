"""Advance a scheme from the replies of every subsystem: the one driver of every bus.

A scheme (``manager.scheme.jacobi``) is deterministic: from the scene and the replies it receives it computes
every command. So every process of a run runs the *same* scheme:

* in-process, one replica holds every subsystem and executes every command itself;
* over Zenoh, each subsystem process holds its own subsystem, executes only its own commands and
  publishes its replies, and takes the other subsystems' replies from the network: a macro-step costs
  one network hop instead of the two of a manager in the loop (manager → subsystem → manager);
* the manager runs the replica that holds no subsystem: it monitors, records and checks, for every
  reply, that the subsystem executed exactly the command the manager's replica computed (CRC-32 in
  the reply header). A replica that diverged (different software, different arithmetic) is named at
  the first reply that shows it.

A :class:`Tap` sees what a replica goes through: the commands of each exchange (``commands``, subsystem
→ message), the replies of each exchange when the scheme takes them (``replies``, in simulation order
whether they were computed here or came from the network) and, when the scheme reports it, the status
after every macro-step (``status``). One call per exchange, not per message: a recorded run taps the
in-process replica, on the stepping loop, or the manager's replica that follows a Zenoh run.
:class:`PerMessage` makes a tap of a function of ``(source, channel, message)``.
"""
from __future__ import annotations

from collections import deque
from typing import Callable, Generator, Protocol

from zencosim.manager.scheme.base import Exchange, RunRecord
from zencosim.manager.wire.protocol import HEADER, ProtocolError, command_ref


class Tap(Protocol):
    """What sees every message of a replica (see the module text)."""

    def status(self, message: bytes) -> None:
        """The status after a macro-step (channel ``manager/status``)."""

    def commands(self, sends: dict[str, bytes]) -> None:
        """The commands of an exchange (channels ``<sub>/commands``)."""

    def replies(self, replies: dict[str, bytes]) -> None:
        """The replies the scheme takes (channels ``<sub>/y``)."""


class PerMessage:
    """A :class:`Tap` that hands each message to ``tap(source, channel, message)``."""

    def __init__(self, tap: Callable[[str, str, bytes], None]) -> None:
        self.tap = tap

    def status(self, message: bytes) -> None:
        self.tap("manager", "status", message)

    def commands(self, sends: dict[str, bytes]) -> None:
        for name, command in sends.items():
            self.tap(name, "commands", command)

    def replies(self, replies: dict[str, bytes]) -> None:
        for name, reply in replies.items():
            self.tap(name, "y", reply)


class Replica:
    """One copy of a run's scheme; ``local`` are the subsystem endpoints this process executes."""

    def __init__(self, scheme: Generator[Exchange, dict[str, bytes], RunRecord], names: list[str],
                 local: dict | None = None, publish: Callable[[str, bytes], None] | None = None,
                 verify: bool = False, tap: Tap | None = None) -> None:
        self.scheme = scheme
        self.local = local or {}
        self.publish = publish
        self.verify = verify
        self.tap = tap
        self.replies: dict[str, deque[bytes]] = {name: deque() for name in names}
        self.expected: dict[str, deque[int]] = {name: deque() for name in names}
        self.request: Exchange | None = None
        self.result: RunRecord | None = None
        self.steps_done = 0

    @property
    def finished(self) -> bool:
        return self.result is not None

    def waiting_for(self) -> list[str]:
        """Subsystems whose reply the scheme waits for now."""
        if self.request is None:
            return []
        return [name for name in self.request.awaits if not self.replies[name]]

    def start(self) -> None:
        self.request = next(self.scheme)
        self._execute()
        self._advance()

    def deliver(self, name: str, reply: bytes) -> None:
        """A reply of subsystem ``name`` from the network."""
        self.replies[name].append(reply)
        if self.request is not None:
            self._advance()

    def run(self) -> RunRecord:
        """Run to the end when every subsystem is local (the in-process bus)."""
        self.start()
        if not self.finished:
            raise RuntimeError(f"the scheme waits for {self.waiting_for()}, which no endpoint answers")
        return self.result

    def _execute(self) -> None:
        tap = self.tap
        if tap is not None:
            if self.request.status is not None:
                tap.status(self.request.status)
            tap.commands(self.request.sends)
        for name, command in self.request.sends.items():
            if self.verify:
                self.expected[name].append(command_ref(command))
            endpoint = self.local.get(name)
            if endpoint is not None:
                reply = endpoint.handle(command)
                if self.publish is not None:
                    self.publish(name, reply)
                self.replies[name].append(reply)

    def _advance(self) -> None:
        waiting = self.replies
        while True:
            awaits = self.request.awaits
            for name in awaits:
                if not waiting[name]:
                    return
            replies = {name: waiting[name].popleft() for name in awaits}
            if self.tap is not None:
                self.tap.replies(replies)
            if self.verify:
                for name, reply in replies.items():
                    self._check(name, reply)
            try:
                self.request = self.scheme.send(replies)
            except StopIteration as done:
                self.result = done.value
                self.request = None
                return
            self.steps_done += 1
            self._execute()

    def _check(self, name: str, reply: bytes) -> None:
        expected = self.expected[name].popleft()
        ref = HEADER.unpack_from(reply)[6] if len(reply) >= HEADER.size else None
        if ref != expected:
            raise ProtocolError(f"subsystem {name} executed a command that differs from the manager's "
                                f"(reference {ref} instead of {expected}): its copy of the scheme diverged; "
                                "run every process with the same zencosim, numpy and scene")
