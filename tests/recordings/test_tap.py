"""The recorder's tap under SIGINT/SIGTERM, which end a run by an exception wherever it happens to be.

The frames the tap would send down the pipe are captured instead (no recorder process), so the test
can look at each one: its declared message count must match its channel indices, and what was
counted as handed over must be exactly what was sent.
"""
from __future__ import annotations

import marshal
import os
import signal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import Exchange
from zencosim.manager.wire.protocol import Kind, decode
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.recorder import BATCH_MESSAGES, Recorder
from zencosim.recordings.recorder_process import BATCH_HEAD, split_batch

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


class CapturingRecorder(Recorder):
    """A tap whose frames are kept here; ``during_write`` runs while a frame is being sent."""

    def __init__(self, tmp_path, realtime: bool = False, hold_signals: bool = False) -> None:
        super().__init__(tmp_path / "unused.mcap")
        plan, _ = plan_scene(load_scene("two_mass_damped"))
        self.report = StatusReport(plan, realtime)
        self._declare(plan, self.report, realtime)
        if hold_signals:  # as start() does; close() puts the handlers back
            self._hold_signals()
        self.frames: list[bytes] = []
        self.during_write = lambda: None

    def status(self, step: int) -> int:
        """Step ``step`` ends, as a scheme logs it (δP and δE equal to the step, completed 1 µs after its release);
        the exchange's status."""
        self.report.log_residuals([float(step)] * self.report.n_residuals)
        self.report.log_times((step, 1000 * step, 1000 * step + 1000, -step))
        return step

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        self.during_write()
        self.frames.append(payload)


def _status_of(message: bytes) -> tuple[int, list[float]]:
    """(step, values) of a STATUS message."""
    decoded = decode(message, "the tap")
    assert decoded.kind == Kind.STATUS
    return decoded.step, decoded.values.tolist()


def _each(sizes, blob: bytes) -> list[bytes]:
    """The messages of a batch (``split_batch``: one after the other)."""
    ends = np.cumsum(sizes).tolist()
    return [blob[end - size:end] for end, size in zip(ends, sizes.tolist())]


def _messages_in(frame: bytes) -> tuple[int, int]:
    """(messages, status stamps) a batch frame declares; checks that its channel indices agree."""
    n, stamps, _ = BATCH_HEAD.unpack_from(frame)
    channels = frame[BATCH_HEAD.size:BATCH_HEAD.size + n]
    assert len(channels) == n
    return n, stamps


class _InterruptedDict(dict):
    """Commands whose names cannot be taken, as when a signal arrives between two statements of the tap: after the
    exchange's messages went in, before their channel indices."""

    def __iter__(self):
        raise KeyboardInterrupt


def test_a_tap_cut_short_by_an_interrupt_leaves_no_half_message(tmp_path):
    recorder = CapturingRecorder(tmp_path)
    for step in range(3):
        recorder.exchange(None if step == 0 else {"S2": b"y%d" % step},
                          Exchange({"S1": b"c%d" % step}, ("S2",), recorder.status(step)))
    with pytest.raises(KeyboardInterrupt):  # the messages go in, their channel indices do not
        recorder.exchange({"S2": b"y3"}, Exchange(_InterruptedDict(S1=b"cut"), ("S2",)))
    assert len(recorder._messages) == 7
    recorder.flush()  # what finish() does after an interrupted run
    assert [_messages_in(frame) for frame in recorder.frames] == [(8, 3)]
    channels, sizes, stamps, blob = split_batch(recorder.frames[0], recorder._status)
    messages = _each(sizes, blob)
    assert messages[1::3] == [b"c0", b"c1", b"c2"] and messages[2::3] == [b"y1", b"y2"]  # the replica's order
    # each status encoded from the log: its step, δP and δE as logged, wall time since step 0's release, step time
    assert [_status_of(message) for message in messages[::3]] == [
        (step, [float(step), float(step), (1000 * step + 1000) * 1e-9, 1000 * 1e-9]) for step in range(3)]
    assert np.diff(stamps).tolist() == [1000, 1000]  # stamped when each step completed, on the wall clock
    assert [recorder._topics[i] for i in channels] == ["manager/status", "S1/commands"] + [
        "S2/y", "manager/status", "S1/commands"] * 2
    assert recorder.published == {**dict.fromkeys(recorder.published, 0), "manager/status": 3, "S1/commands": 3,
                                  "S2/y": 2}


def test_a_signal_during_a_flush_acts_after_the_frame_is_sent_and_counted(tmp_path):
    sent_before_interrupt = []

    def interrupt(*_) -> None:  # as cli.main's SIGTERM handler
        sent_before_interrupt.append(len(recorder.frames))
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        recorder = CapturingRecorder(tmp_path, hold_signals=True)
        recorder.exchange(None, Exchange({"S1": b"c"}, ("S1",), recorder.status(0)))
        recorder.during_write = lambda: os.kill(os.getpid(), signal.SIGTERM)
        with pytest.raises(KeyboardInterrupt):
            recorder.flush()
        assert sent_before_interrupt == [1]  # the handler ran once, after the frame was sent
        assert [_messages_in(frame) for frame in recorder.frames] == [(2, 1)]
        assert sum(recorder.published.values()) == 2 and not recorder._messages  # counted and cleared once
        recorder.during_write = lambda: None
        with pytest.raises(KeyboardInterrupt):  # outside a flush the handler acts at once
            os.kill(os.getpid(), signal.SIGTERM)
        assert sent_before_interrupt == [1, 1]
        recorder.close()
        assert signal.getsignal(signal.SIGTERM) is interrupt  # the run's handlers put back
    finally:
        signal.signal(signal.SIGTERM, previous)


_MESSAGE = st.binary(min_size=1, max_size=40)
_STEP = st.tuples(st.dictionaries(st.sampled_from(["S1", "S2"]), _MESSAGE),  # the replies taken
                  st.dictionaries(st.sampled_from(["S1", "S2"]), _MESSAGE),  # the commands sent
                  st.booleans(),  # whether the exchange reports a status
                  st.booleans())  # whether it has a shape (Exchange.shape: one per set of names)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(exchanges=st.lists(_STEP, min_size=1, max_size=30))
def test_a_batch_frame_gives_back_every_message_in_the_order_the_replica_went_through_them(tmp_path_factory, exchanges):
    """The frame holds the statuses after the other messages (taken from the status log at the flush); read back,
    every message is where the replica went through it, whatever the mix of channels, sizes and shapes."""
    recorder = CapturingRecorder(tmp_path_factory.mktemp("frames"))
    expected, step, awaited, shapes = [], 0, None, {}
    for replies, sends, reports, shaped in exchanges:
        replies = {name: replies.get(name, b"y") for name in awaited} if awaited else None
        for name, reply in (replies or {}).items():
            expected.append((f"{name}/y", reply))
        status = recorder.status(step) if reports else None
        if reports:
            expected.append(("manager/status", ("status", step)))
            step += 1
        expected += [(f"{name}/commands", command) for name, command in sends.items()]
        names = (awaited, reports, tuple(sends))  # with the awaits, which are the sends' names here
        recorder.exchange(replies, Exchange(sends, tuple(sends), status, None,
                                            shapes.setdefault(names, len(shapes)) if shaped else None))
        awaited = tuple(sends)
    recorder.flush()
    if not expected:
        assert recorder.frames == []
        return
    (frame,) = recorder.frames
    channels, sizes, stamps, blob = split_batch(frame, recorder._status)
    found = [(recorder._topics[i], message) for i, message in zip(channels.tolist(), _each(sizes, blob))]
    assert [(topic, ("status", _status_of(message)[0]) if topic == "manager/status" else message)
            for topic, message in found] == expected
    assert len(stamps) == step


def test_a_real_time_run_is_handed_over_every_10_ms_of_its_steps(tmp_path):
    """two_mass_damped steps 1 ms: a real-time run's batches go at every tenth status (a live view sees the run
    at 100 frames per second), each holding whole steps — a step's replies, its status with the lateness the
    scheme logged, the next commands."""
    recorder = CapturingRecorder(tmp_path, realtime=True)
    for step in range(35):
        recorder.exchange(None if step == 0 else {"S2": b"y"}, Exchange({"S1": b"c"}, ("S2",), recorder.status(step)))
    recorder.flush(last=True)
    held = []
    for frame in recorder.frames:
        channels, sizes, stamps, blob = split_batch(frame, recorder._status)
        statuses = [_status_of(message) for i, message in zip(channels.tolist(), _each(sizes, blob))
                    if i == recorder._status]
        assert len(stamps) == len(statuses)
        assert [recorder._topics[i] for i in channels] == [  # whole steps (step 0 has no replies)
            topic for step, _ in statuses for topic in ["S2/y"] * (step > 0) + ["manager/status", "S1/commands"]]
        held.append([step for step, _ in statuses])
        assert [values[-1] for _, values in statuses] == [-step * 1e-9 for step, _ in statuses]  # the lateness
    assert held == [list(range(0, 10)), list(range(10, 20)), list(range(20, 30)), list(range(30, 35))]


def test_a_batch_holds_at_most_its_size_in_messages_counting_the_statuses(tmp_path):
    """Steps at which no subsystem is due (multi-rate) have a status and nothing else: the statuses count towards a
    batch's size, so the status log a batch takes stays as bounded as its messages."""
    recorder = CapturingRecorder(tmp_path)
    for step in range(5000):
        recorder.exchange(None, Exchange({}, (), recorder.status(step)))
    recorder.flush(last=True)
    size = BATCH_MESSAGES
    assert [_messages_in(frame) for frame in recorder.frames] == [(size, size), (size, size), (5000 - 2 * size,) * 2]
    assert recorder.report.logged == 0


def test_a_batch_frame_that_does_not_hold_what_its_head_says_is_refused(tmp_path):
    """A frame cut short, whose statuses' bytes are no whole number of statuses, or whose list of messages holds
    another number of messages or something else than messages, is refused by name — not read as nonsense."""
    recorder = CapturingRecorder(tmp_path)
    for step in range(3):
        recorder.exchange(None if step == 0 else {"S2": b"y%d" % step},
                          Exchange({"S1": b"c%d" % step}, ("S2",), recorder.status(step)))
    recorder.flush()
    (frame,) = recorder.frames
    split_batch(frame, recorder._status)  # whole, it reads
    n, m, statuses_bytes = BATCH_HEAD.unpack_from(frame)
    others_at = BATCH_HEAD.size + n + 8 * m + statuses_bytes
    for damaged in (frame[:-1],  # cut short in the list of messages
                    BATCH_HEAD.pack(n, m, statuses_bytes - 1) + frame[BATCH_HEAD.size:],  # statuses: a byte less
                    frame[:others_at] + marshal.dumps([b"c0", b"c1"]),  # a message less
                    frame[:others_at] + marshal.dumps([1, 2, 3, 4, 5])):  # numbers, not messages
        with pytest.raises(ValueError, match=r"a batch frame of 8 messages \(3 statuses, \d+ bytes\) that does not "
                                             r"hold them"):
            split_batch(damaged, recorder._status)
