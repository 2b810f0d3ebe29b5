"""A recorder's tap with its frames kept in the test's process (no recorder process), and the messages they hold."""
from __future__ import annotations

import numpy as np

from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.recorder import Recorder
from zencosim.recordings.recorder_process import frame_messages


class FramesRecorder(Recorder):
    """The recorder's tap with its frames kept here (no recorder process)."""

    def __init__(self, plan, status: StatusReport) -> None:
        super().__init__(None)
        self._declare(plan, status, False)
        self.frames: list[tuple[int, bytes]] = []

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        self.frames.append((kind, payload))

    def messages(self, residuals_end: int) -> list[tuple[int, bytes]]:
        """Every message of the frames, (channel index, bytes), a status's only up to ``residuals_end``."""
        found = []
        for kind, frame in self.frames:
            channels, sizes, _, blob = frame_messages(kind, frame, self._index, self._status)
            ends = np.cumsum(sizes).tolist()
            found += [(i, blob[end - size:end][:residuals_end] if i == self._status else blob[end - size:end])
                      for i, size, end in zip(channels.tolist(), sizes.tolist(), ends)]
        return found
