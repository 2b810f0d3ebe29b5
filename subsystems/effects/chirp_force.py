"""External force: a linear chirp (paper 000 §5.3)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class ChirpForce:
    """``f(t) = A sin(2π (f0 t + (f1 − f0) t² / (2 T)))`` for ``t <= T``, continuing at ``f1`` after.

    The instantaneous frequency sweeps linearly from ``f_start`` at t = 0 to ``f_end`` at t = T
    (paper 000 §5.3: 1 N, 1 → 10 Hz on m2).
    """

    amplitude: float = field(metadata=quantity("N", kind="force"))  # A [N]
    f_start_hz: float = field(metadata=quantity("Hz", kind="frequency"))  # f0 [Hz]
    f_end_hz: float = field(metadata=quantity("Hz", kind="frequency"))  # f1 [Hz]
    sweep_time: float = field(metadata=quantity("s", kind="sweep time"))  # T [s]

    kind: ClassVar[str] = "external"
    endpoint_counts: ClassVar[tuple[int, ...]] = (1,)

    def active(self) -> bool:
        return self.amplitude != 0.0

    def phase(self, t: float) -> float:
        """Phase [rad] at time t [s]."""
        tau = min(t, self.sweep_time)
        cycles = self.f_start_hz * tau + (self.f_end_hz - self.f_start_hz) * tau * tau / (2.0 * self.sweep_time)
        cycles += self.f_end_hz * (t - tau)
        return 2.0 * math.pi * cycles

    def force(self, t: float) -> float:
        """Force [N] at time t [s]."""
        return self.amplitude * math.sin(self.phase(t))
