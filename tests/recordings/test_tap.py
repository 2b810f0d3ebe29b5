"""The recorder's tap under SIGINT/SIGTERM, which end a run by an exception wherever it happens to be.

The frames the tap would send down the pipe are captured instead (no recorder process), so the test
can look at each one: its declared message count must match its channel indices, and what was
counted as handed over must be exactly what was sent.
"""
from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import Exchange
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.layout import channel_specs
from zencosim.recordings.recorder import Recorder
from zencosim.recordings.recorder_process import BATCH_HEAD, split_batch

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


class CapturingRecorder(Recorder):
    """A tap whose frames are kept here; ``during_write`` runs while a frame is being sent."""

    def __init__(self, tmp_path) -> None:
        super().__init__(tmp_path / "unused.mcap")
        plan, _ = plan_scene(load_scene("two_mass_damped"))
        self._declare(channel_specs(plan, StatusReport(plan, False)), realtime=False)
        self.frames: list[bytes] = []
        self.during_write = lambda: None

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        self.during_write()
        self.frames.append(payload)


def _messages_in(frame: bytes) -> tuple[int, int]:
    """(messages, status stamps) a batch frame declares; checks that its channel indices agree."""
    n, stamps = BATCH_HEAD.unpack_from(frame)
    channels = frame[BATCH_HEAD.size:BATCH_HEAD.size + n]
    assert len(channels) == n
    return n, stamps


class _InterruptedDict(dict):
    """Messages whose values cannot be taken, as when a signal arrives between two statements of the tap."""

    def values(self):
        raise KeyboardInterrupt


def test_a_tap_cut_short_by_an_interrupt_leaves_no_half_message(tmp_path):
    recorder = CapturingRecorder(tmp_path)
    for step in range(3):
        recorder.exchange(None if step == 0 else {"S2": b"y%d" % step},
                          Exchange({"S1": b"c%d" % step}, ("S2",), b"s%d" % step))
    with pytest.raises(KeyboardInterrupt):  # the channel index goes in, the message does not
        recorder.exchange(_InterruptedDict(S2=b"cut"), None)
    recorder.flush()  # what finish() does after an interrupted run
    assert [_messages_in(frame) for frame in recorder.frames] == [(8, 3)]
    channels, sizes, _, blob = split_batch(recorder.frames[0])
    ends = np.cumsum(sizes)
    assert [blob[end - size:end] for size, end in zip(sizes, ends)] == [  # the replica's order
        b"s0", b"c0", b"y1", b"s1", b"c1", b"y2", b"s2", b"c2"]
    assert [recorder._topics[i] for i in channels] == ["manager/status", "S1/commands"] + [
        "S2/y", "manager/status", "S1/commands"] * 2
    assert recorder.published == {**dict.fromkeys(recorder.published, 0), "manager/status": 3, "S1/commands": 3,
                                  "S2/y": 2}


def test_a_signal_during_a_flush_acts_after_the_frame_is_sent_and_counted(tmp_path):
    recorder = CapturingRecorder(tmp_path)
    recorder.exchange(None, Exchange({"S1": b"c"}, ("S1",), b"s"))
    sent_before_interrupt = []

    def interrupt(*_) -> None:  # as cli.main's SIGTERM handler
        sent_before_interrupt.append(len(recorder.frames))
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    recorder.during_write = lambda: os.kill(os.getpid(), signal.SIGTERM)
    try:
        with pytest.raises(KeyboardInterrupt):
            recorder.flush()
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert sent_before_interrupt == [1]  # the handler ran once, after the frame was sent
    assert [_messages_in(frame) for frame in recorder.frames] == [(2, 1)]
    assert sum(recorder.published.values()) == 2 and not recorder._messages  # counted and cleared once
    assert signal.getsignal(signal.SIGTERM) is previous
