"""Linear viscous damper between two points, or between a point and the ground."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from zencosim.subsystems.effects.spring import stamp_pair
from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class Damper:
    """``f_a = -c (v_a - v_b)`` on point a and the opposite force on point b (paper 000 Eq. 8)."""

    damping: float = field(metadata=quantity("N s/m", kind="damping"))  # c [N s/m]

    kind: ClassVar[str] = "linear"
    endpoint_counts: ClassVar[tuple[int, ...]] = (1, 2)
    free_length: ClassVar[float] = 0.0

    def active(self) -> bool:
        return self.damping != 0.0

    def stamp(self, K: np.ndarray, C: np.ndarray, a: int, b: int | None) -> None:
        """Add this damper to the damping matrix of the point coordinates."""
        stamp_pair(C, a, b, self.damping)

    def force(self, elongation: float, rate: float) -> float:
        """Force [N] on point a along the elongation, for elongation [m] and its rate [m/s]."""
        return -self.damping * rate

    def potential(self, elongation: float) -> float:
        return 0.0
