"""Linear spring between two points, or between a point and the ground."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from zencosim.subsystems.params import quantity


def stamp_pair(matrix: np.ndarray, a: int, b: int | None, coefficient: float) -> None:
    """Add a two-point element ``coefficient`` between coordinates ``a`` and ``b`` (None: the ground)."""
    matrix[a, a] += coefficient
    if b is not None:
        matrix[b, b] += coefficient
        matrix[a, b] -= coefficient
        matrix[b, a] -= coefficient


@dataclass(frozen=True)
class Spring:
    """``f_a = -k (x_a - x_b)`` on point a and the opposite force on point b (paper 000 Eq. 8).

    Between two points in the plane the elongation is ``|r_a - r_b| - free_length`` and the force acts
    along the line between them (see ``subsystems.effects``); on a line ``free_length`` must be 0.
    """

    stiffness: float = field(metadata=quantity("N/m", kind="stiffness"))  # k [N/m]
    free_length: float = field(default=0.0, metadata=quantity("m", kind="free length"))  # l0 [m], planar elements only

    kind: ClassVar[str] = "linear"
    endpoint_counts: ClassVar[tuple[int, ...]] = (1, 2)

    def active(self) -> bool:
        return self.stiffness != 0.0

    def stamp(self, K: np.ndarray, C: np.ndarray, a: int, b: int | None) -> None:
        """Add this spring to the stiffness matrix of the point coordinates."""
        stamp_pair(K, a, b, self.stiffness)

    def force(self, elongation: float, rate: float) -> float:
        """Force [N] on point a along the elongation, for elongation [m] and its rate [m/s]."""
        return -self.stiffness * elongation

    def potential(self, elongation: float) -> float:
        """Stored energy [J]."""
        return 0.5 * self.stiffness * elongation * elongation
