"""A recorder's tap with its frames kept in the test's process (no recorder process), and the messages they hold."""
from __future__ import annotations

import numpy as np

from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.recorder import Recorder
from zencosim.recordings.recorder_process import FRAME, PENDING, frame_messages


class _KeptPipe:
    """The recorder process's pipe, as the frames sent to it alone (PENDING frames) reach it: kept in ``pending``, each
    with the number of the other frames sent before it."""

    gone = None

    def __init__(self, frames: list[tuple[int, bytes]]) -> None:
        self.frames = frames
        self.pending: list[tuple[int, bytes]] = []

    def write(self, parts: tuple[bytes], _stall_s, _stalled) -> None:
        assert FRAME.unpack_from(parts[0])[0] == PENDING
        self.pending.append((len(self.frames), parts[0][FRAME.size:]))


class FramesRecorder(Recorder):
    """The recorder's tap with its frames kept here (no recorder process); ``pending``: the PENDING frames, each after
    how many of ``frames``."""

    def __init__(self, plan, status: StatusReport) -> None:
        super().__init__(None)
        self._declare(plan, status, False)
        self.frames: list[tuple[int, bytes]] = []
        self._recorder = _KeptPipe(self.frames)
        self.pending = self._recorder.pending

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        self.frames.append((kind, payload))

    def messages(self, residuals_end: int) -> list[tuple[int, bytes]]:
        """Every message of the frames, (channel index, bytes), a status's only up to ``residuals_end``."""
        return self.frames_messages(self.frames, residuals_end)

    def frames_messages(self, frames: list[tuple[int, bytes]], residuals_end: int) -> list[tuple[int, bytes]]:
        """Every message of ``frames`` (BATCH, STEPS, ROWS), as :meth:`messages` gives them."""
        found = []
        for kind, frame in frames:
            channels, sizes, _, blob = frame_messages(kind, frame, self._index, self._status)
            ends = np.cumsum(sizes).tolist()
            found += [(i, blob[end - size:end][:residuals_end] if i == self._status else blob[end - size:end])
                      for i, size, end in zip(channels.tolist(), sizes.tolist(), ends)]
        return found
