"""Two-point elements between points in the plane: the line geometry around a scalar force law.

An element between points a and b with positions ``r`` and velocities ``v`` has the unit vector
``e = (r_a − r_b)/|r_a − r_b|``, the elongation ``η = |r_a − r_b| − l0`` (``l0`` its free length) and
the elongation rate ``η̇ = e · (v_a − v_b)``; it exerts ``force(η, η̇) e`` on a and the opposite on b
(see ``subsystems.effects``). Coincident points have no direction: an element whose points coincide
is refused rather than given an arbitrary one.
"""
from __future__ import annotations

import math

import numpy as np


def planar_force(effect, r_a: np.ndarray, v_a: np.ndarray, r_b: np.ndarray, v_b: np.ndarray) -> tuple[np.ndarray, float]:
    """Force [N] of a two-point ``effect`` on point a, and the energy [J] it stores."""
    d = r_a - r_b
    distance = math.hypot(d[0], d[1])
    if distance == 0.0:
        raise ValueError(f"planar element {effect!r}: its two points coincide, the force has no direction")
    e = d / distance
    elongation = distance - effect.free_length
    rate = float(e.dot(v_a - v_b))
    return effect.force(elongation, rate) * e, effect.potential(elongation)
