"""Nonlinear damper whose force grows with the square of the elongation rate (paper 002 Eq. 23)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class QuadraticDamper:
    """``f_a = -c sgn(η̇) η̇²`` on point a, ``η̇ = v_a - v_b`` (paper 002 Eq. 23), opposite on point b."""

    damping: float = field(metadata=quantity("N s^2/m^2", kind="quadratic damping"))  # c [N s² m⁻²]

    kind: ClassVar[str] = "nonlinear"
    endpoint_counts: ClassVar[tuple[int, ...]] = (1, 2)
    free_length: ClassVar[float] = 0.0

    def active(self) -> bool:
        return self.damping != 0.0

    def force(self, elongation: float, rate: float) -> float:
        """Force [N] on point a for the elongation rate [m/s]."""
        return -self.damping * rate * abs(rate)

    def potential(self, elongation: float) -> float:
        return 0.0
