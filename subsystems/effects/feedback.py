"""Compensation feedback term: a force on one point proportional to the motion of another."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class Feedback:
    """``f_target = -(d a_source + f v_source + g x_source)``: one term ``r(s) x`` of paper 000 Eqs. 24, 47.

    Not symmetric (no reaction on the source) and not named by scenes: the eigenstructure
    compensator (``manager.analysis.compensator``) attaches it. A model stamps it into point-coordinate
    matrices; the acceleration gain ``d`` acts as an added mass (``MassesModel``).
    """

    acceleration_gain: float = field(metadata=quantity("kg"))  # d [kg]
    velocity_gain: float = field(metadata=quantity("N s/m"))  # f [N s/m]
    displacement_gain: float = field(metadata=quantity("N/m"))  # g [N/m]

    kind: ClassVar[str] = "feedback"
    endpoint_counts: ClassVar[tuple[int, ...]] = (2,)

    def active(self) -> bool:
        return any(gain != 0.0 for gain in (self.acceleration_gain, self.velocity_gain, self.displacement_gain))

    def stamp(self, Mq: np.ndarray, K: np.ndarray, C: np.ndarray, target: int, source: int) -> None:
        """Add the gains at ``[target, source]`` of the added-mass, stiffness and damping matrices."""
        Mq[target, source] += self.acceleration_gain
        K[target, source] += self.displacement_gain
        C[target, source] += self.velocity_gain
