"""Replay verification: re-run a recording's embedded scene in process and compare every channel bit for bit.

The re-run is the in-process replica with a tap that compares each message, as it is produced, with
the next recorded message of the same channel: kind, step, time, rows, reference, and every float64
value by its bits (NaN included). The status's measured fields (wall-clock times) are not compared. The first
difference stops the re-run and is reported with its channel, step, value name and both values; a
recording that ends early (a failed or interrupted run) is compared up to its last message; one with no
message to compare never passes (it verifies nothing). A run that failed in its model (a subsystem's failure) fails
again in the re-run, after its last recorded message: the verdict is on the messages, and the re-run's failure is
given beside the recorded outcome; a re-run that fails before the recording's end does not pass.

The re-run is planned for no more macro-steps than the recording holds statuses (plus one; an energy-controlled
run, whose steps vary: up to its last status), so what it allocates is bounded by the file's size
(``recordings.mcap_read`` bounds what the file may hold), never by the duration its scene claims. A verification
passes only when the file is intact as well (``Recording.intact``: read to its end, every CRC, count and digest
checked): a damaged or cut-off file never passes, whatever its messages.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import run_in_process
from zencosim.manager.bus.watchdog import model_watch
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.replica import PerMessage
from zencosim.manager.wire.protocol import Kind, decode
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings import RecordingError
from zencosim.recordings.layout import STATUS_TOPIC, channel_specs
from zencosim.recordings.reader import Recording


@dataclass(frozen=True)
class Divergence:
    channel: str
    step: int
    what: str  # the field or value name that differs
    recorded: str
    rerun: str

    def __str__(self) -> str:
        return f"{self.channel} step {self.step}: {self.what} recorded {self.recorded}, re-run {self.rerun}"


@dataclass(frozen=True)
class Verification:
    compared: dict[str, int]  # messages compared per channel
    last_step: int  # the last step whose status was compared
    divergence: Divergence | None
    note: str  # why the comparison ended before the end of the re-run or of the recording, or ""
    completed_run: bool  # the recording says its run completed: then it must hold every message
    truncated: str | None  # why the file was read only in part (Recording.truncated)
    damage: tuple[str, ...]  # every check the file failed (Recording.damage)
    failure: str | None = None  # why the re-run failed (a subsystem's failure), once it had compared what it could
    outcome: str | None = None  # the recorded run's outcome (its end record), when the recorder finished

    @property
    def reproduced(self) -> bool:
        """The re-run failed as the recorded run did (the same reason)."""
        return self.failure is not None and self.outcome == f"failed: {self.failure}"

    @property
    def empty(self) -> bool:
        """No message was compared: the recording holds none to verify (or none the re-run reached)."""
        return not sum(self.compared.values())

    @property
    def passed(self) -> bool:
        """Every message bit-identical, the file intact; a re-run that failed did so only after every recorded message
        and where the recorded run did not complete."""
        return (self.divergence is None and not ((self.completed_run or self.failure is not None) and self.note)
                and not (self.completed_run and self.failure is not None) and self.truncated is None
                and not self.damage and not self.empty)


class _Stop(Exception):
    """Ends the re-run early: the recording diverged, or has no more messages."""


def _kind_name(kind: int) -> str:
    return Kind(kind).name if kind in Kind._value2member_map_ else str(kind)


def _value_text(x: float) -> str:
    return f"{x!r} (0x{np.float64(x).view(np.uint64):016x})"


class _Comparer:
    """The tap of the re-run: compares every message with the recording's next one on the same channel."""

    def __init__(self, recording: Recording, status_names: tuple[str, ...], all_compared: Callable[[], None]) -> None:
        self.recording = recording
        self.cursor = {topic: 0 for topic in recording.channels}
        self.left = sum(len(channel.messages) for channel in recording.channels.values())  # not yet compared
        self.all_compared = all_compared  # called once the last is
        self.divergence: Divergence | None = None
        self.exhausted: str | None = None
        self.last_step = 0
        spec = recording.channels[STATUS_TOPIC].spec
        compared = [n for n in spec.names if n not in spec.measured]
        missing = [n for n in compared if n not in status_names]
        if missing:
            raise RecordingError(f"{recording.path}: this zencosim reports no status fields {', '.join(missing)}")
        self.status_pairs = [(spec.names.index(n), status_names.index(n), n) for n in compared]

    def tap(self, source: str, channel: str, wire: bytes) -> None:
        topic = f"{source}/{channel}"
        messages = self.recording.channels[topic].messages
        message = decode(wire, topic)
        index = self.cursor[topic]
        if index >= len(messages):
            self.exhausted = (f"{topic} has no message after step {messages[-1].step}" if messages
                              else f"the recording holds no message of {topic}")
            raise _Stop
        self.cursor[topic] = index + 1
        self.left -= 1
        recorded = messages[index]
        if recorded.kind != message.kind:
            self._diverged(topic, message.step, "kind", _kind_name(recorded.kind), message.kind.name)
        for what, old, new in (("step", recorded.step, message.step), ("time_ns", recorded.time_ns, message.time_ns),
                               ("rows", recorded.rows, message.rows), ("ref", recorded.ref, message.ref)):
            if old != new:
                self._diverged(topic, message.step, what, str(old), str(new))
        if message.kind == Kind.ERROR:
            if recorded.text != message.text():
                self._diverged(topic, message.step, "error text", recorded.text, message.text())
        else:
            self._compare_values(topic, message, recorded)
        if not self.left:
            self.all_compared()

    def _compare_values(self, topic: str, message, recorded) -> None:
        """The values of the re-run's ``message`` of ``topic`` against the ``recorded`` one, bit for bit."""
        if topic == STATUS_TOPIC:
            pairs = self.status_pairs
            self.last_step = message.step
            if recorded.values.size != len(self.recording.channels[topic].spec.names):
                self._diverged(topic, message.step, "number of values", str(recorded.values.size),
                               str(len(self.recording.channels[topic].spec.names)))
        else:
            if recorded.values.size != message.values.size:
                self._diverged(topic, message.step, "number of values", str(recorded.values.size),
                               str(message.values.size))
            names = self.recording.channels[topic].spec.names
            pairs = [(i, i, names[i % len(names)] + (f" (row {i // len(names)})" if message.rows > 1 else ""))
                     for i in range(message.values.size)]
        old_bits, new_bits = recorded.values.view(np.uint64), message.values.view(np.uint64)
        for old_at, new_at, name in pairs:
            if old_bits[old_at] != new_bits[new_at]:
                self._diverged(topic, message.step, name, _value_text(recorded.values[old_at]),
                               _value_text(message.values[new_at]))

    def _diverged(self, topic: str, step: int, what: str, recorded: str, rerun: str) -> None:
        self.divergence = Divergence(topic, step, what, recorded, rerun)
        raise _Stop


def _cut_to(scene: Scene, steps: int) -> Scene:
    """``scene`` lasting at most ``steps`` macro-steps (rounded up to whole periods of its communication
    ratios): the re-run is planned for what the file holds, so a duration the file claims sizes nothing."""
    period = math.lcm(*(s.settings.comm_ratio for s in scene.subsystems.values()))
    ticks = -(-steps // period) * period
    if ticks * scene.manager.macro_step_ns >= scene.manager.duration_ns:
        return scene
    return replace(scene, manager=replace(scene.manager, duration=ticks * scene.manager.macro_step_ns * 1e-9))


def verify(recording: Recording, compared: Callable[[Verification], None] = lambda result: None) -> Verification:
    """Re-run ``recording``'s scene in process and compare; raise RecordingError when it cannot be re-run.
    ``compared(result)`` is called once every recorded message has been compared, with the verdict so far, when the
    re-run goes on (to a failure of the recorded run's model, which may end the process: ``zencosim replay --verify``
    has it said then, ``manager.bus.watchdog``)."""
    statuses = recording.channels[STATUS_TOPIC].messages if STATUS_TOPIC in recording.channels else []
    scene = recording.scene()
    # energy-controlled steps vary: the re-run ends at the last status recorded (its base step), which it reaches by
    # the same steps; at a fixed step it is planned for the statuses held, plus one
    energy = scene.manager.step_control == "energy"
    held = max(1, max((message.step for message in statuses), default=0)) if energy else len(statuses) + 1
    scene = _cut_to(scene, held)
    try:
        plan, subsystems = plan_scene(scene)
    except (ValueError, TypeError, KeyError, AttributeError, IndexError, ArithmeticError, RecursionError) as error:
        raise RecordingError(f"{recording.path}: its scene cannot be planned ({type(error).__name__}: {error})"
                             f"{recording.damage_note()}") from None
    plan = replace(plan, n_ticks=min(plan.n_ticks, held))  # the re-run ends once it has passed the recording
    status = StatusReport(plan, realtime=False)
    expected = {spec.topic: spec for spec in channel_specs(plan, status)}
    if set(expected) != set(recording.channels):
        raise RecordingError(f"{recording.path}: channels {', '.join(recording.channels)}; scene {scene.name} has "
                             f"{', '.join(expected)} in this zencosim")
    for topic, spec in expected.items():
        recorded = recording.channels[topic].spec
        if spec.role != "status" and recorded.names != spec.names:
            raise RecordingError(f"{recording.path}: channel {topic} holds {', '.join(recorded.names)}; "
                                 f"this zencosim has {', '.join(spec.names)}")
    comparer = _Comparer(recording, tuple(f.name for f in status.fields),
                         lambda: compared(_verification(recording, comparer, None)))
    model_watch().start(list(scene.subsystems), scene.manager.timeout)  # a watched re-run names a model that hangs
    failure = None
    try:
        run_in_process(make_scheme(scene, plan, status=status), plan, subsystems, PerMessage(comparer.tap, status))
    except _Stop:
        pass
    except SubsystemFailure as error:  # a run that failed in its model fails again: after its last message, or sooner
        failure = str(error)
    return _verification(recording, comparer, failure)


def _verification(recording: Recording, comparer: _Comparer, failure: str | None) -> Verification:
    """The verdict of ``comparer`` on ``recording``, the re-run having failed with ``failure`` (None: it did not)."""
    note = comparer.exhausted or ""
    if comparer.divergence is None and not note:
        extra = {t: n for t, c in recording.channels.items() if (n := len(c.messages) - comparer.cursor[t])}
        if extra:
            note = "the recording holds more messages than the re-run: " + ", ".join(f"{t} {n}" for t, n in extra.items())
    outcome = recording.end["outcome"] if recording.end is not None else None
    return Verification(dict(comparer.cursor), comparer.last_step, comparer.divergence, note, outcome == "completed",
                        recording.truncated, tuple(recording.damage), failure, outcome)
