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

A ``tap(source, channel, message)`` sees what a replica goes through: every command (``<sub>,
"commands"``), every reply when the scheme takes it (``<sub>, "y"``, in simulation order whether
the reply was computed here or came from the network) and, when the scheme reports it, the status
after every macro-step (``"manager", "status"``). A recorded run taps the in-process replica, or the
manager's replica that follows a Zenoh run.
"""
from __future__ import annotations

from collections import deque
from typing import Callable, Generator

from zencosim.manager.scheme.base import Exchange, RunRecord
from zencosim.manager.wire.protocol import HEADER, ProtocolError, command_ref


class Replica:
    """One copy of a run's scheme; ``local`` are the subsystem endpoints this process executes."""

    def __init__(self, scheme: Generator[Exchange, dict[str, bytes], RunRecord], names: list[str],
                 local: dict | None = None, publish: Callable[[str, bytes], None] | None = None,
                 verify: bool = False, tap: Callable[[str, str, bytes], None] | None = None) -> None:
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
        if tap is not None and self.request.status is not None:
            tap("manager", "status", self.request.status)
        for name, command in self.request.sends.items():
            if self.verify:
                self.expected[name].append(command_ref(command))
            if tap is not None:
                tap(name, "commands", command)
            endpoint = self.local.get(name)
            if endpoint is not None:
                reply = endpoint.handle(command)
                if self.publish is not None:
                    self.publish(name, reply)
                self.replies[name].append(reply)

    def _advance(self) -> None:
        while all(self.replies[name] for name in self.request.awaits):
            replies = {name: self.replies[name].popleft() for name in self.request.awaits}
            if self.tap is not None:
                for name, reply in replies.items():
                    self.tap(name, "y", reply)
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
