"""Nonlinear spring whose force grows with the square root of its elongation (paper 002 Eq. 22)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class SqrtSpring:
    """``f_a = -κ sgn(η) √|η|`` on point a, ``η = x_a - x_b`` (paper 002 Eq. 22), opposite on point b.

    Stored energy ``(2/3) κ |η|^{3/2}``. The stiffness ``df/dη = -κ / (2 √|η|)`` is unbounded at
    η = 0: the force is continuous but not Lipschitz there.
    """

    stiffness: float = field(metadata=quantity("N/m^0.5", kind="root stiffness"))  # κ [N m^-1/2]
    free_length: float = field(default=0.0, metadata=quantity("m", kind="free length"))  # l0 [m], planar elements only

    kind: ClassVar[str] = "nonlinear"
    endpoint_counts: ClassVar[tuple[int, ...]] = (1, 2)

    def active(self) -> bool:
        return self.stiffness != 0.0

    def force(self, elongation: float, rate: float) -> float:
        """Force [N] on point a along the elongation [m]."""
        return -math.copysign(self.stiffness * math.sqrt(abs(elongation)), elongation)

    def potential(self, elongation: float) -> float:
        """Stored energy [J]."""
        return 2.0 / 3.0 * self.stiffness * abs(elongation) ** 1.5
