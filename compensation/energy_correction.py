"""Energy correction of explicit co-simulation (paper 002 §3.2–3.3): the fraction μ of the residual
energy that is energy error (Eqs. 19–21) and the correction force with its accumulator of
uncorrected energy and its caps (Eqs. 13–17).

Sign convention here is the paper's: ``f`` is the coupling force acting on the *receiving*
subsystem (the one that returns the velocity ``v``, paper 002 Fig. 6), and ``f_corr`` is added to it,
so the correction does the work ``f_corr · v`` on the receiving subsystem. (The runtime's force ports
carry the force on the other side; ``manager.correction`` converts.) Vectors (a point in the plane)
use dot products; on a line they have one component.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

MU_SINGLE_RATE = 0.5  # paper 002 §3.3: single rate, one subsystem with direct feedthrough
AT_REST = 1e-9  # a flow no larger than this fraction of the next one's was at rest (EnergyCorrection's guard)


def correction_coefficient(feedthrough: bool, step_feedthrough: Fraction | float, step_other: Fraction | float,
                           order_of_faster: int) -> float:
    """μ of one bond by the rules of paper 002 §3.3 (Eqs. 19–21), for two subsystems.

    ``feedthrough``: whether the force-side output has direct feedthrough (without it nothing is
    extrapolated into an output and μ = 0); ``step_feedthrough`` and ``step_other``: the communication
    steps [s] of the subsystem with and without direct feedthrough (R = h_df / h_ndf, Eq. 19);
    ``order_of_faster``: the extrapolation order of the inputs of the subsystem with the smaller step
    (0 ZOH; FOH and higher share one rule, as the paper states for SOH). Single rate (R = 1): 0.5.

    The paper gives μ for two subsystems; a bond of a larger scene uses the rule of its own two sides.
    """
    if not feedthrough:
        return 0.0
    R = step_feedthrough / step_other
    if R >= 1:  # Eq. 20: the subsystem with direct feedthrough has the larger step
        return float(MU_SINGLE_RATE * (Fraction(3, 2) - Fraction(1, 2) / R)) if order_of_faster == 0 else MU_SINGLE_RATE
    return MU_SINGLE_RATE if order_of_faster == 0 else float(MU_SINGLE_RATE * R)  # Eq. 21


@dataclass
class EnergyCorrection:
    """The correction of one receiving point: Eqs. 14–17 with caps.

    At every correction point t_{k+1} (the end of a macro-step of length H), :meth:`update` takes the
    energy error ζ_{k+1} = μ δE_{k+1} of the step just ended (Eq. 13), the receiving point's velocity
    v_{k+1} and the uncorrected coupling force f_{k+1}, and

    1. closes the previous step: ``U_k = ζ_k + f_corr,k · v_{k+1} H`` (Eq. 15, the energy the previous
       correction left in place, estimated with the velocity now observed) and ``𝒰_k = 𝒰_{k-1} + U_k``
       (Eq. 16);
    2. returns ``f_corr,k+1 = −(ζ_{k+1} + ν 𝒰_k) v_{k+1} / (|v_{k+1}|² H)`` (Eq. 17; on a line this is
       ``−(ζ + ν𝒰)/(v H)``; in the plane it is the smallest force that does that work), limited in
       magnitude to ``cap_fraction |f_{k+1}|`` and to ``cap_force`` (either may be None: no limit) — the
       paper's safeguard for a v that approaches zero (§3.2, after Eq. 14: "the maximum admissible
       correction must be limited … set to a percentage of the uncorrected coupling force").

    Where the division of Eq. 14 has no meaning the force is withheld (zero; ζ then stays in 𝒰 by Eq. 15):
    a zero velocity, and a flow that leaves rest — ``|v_k| <= AT_REST |v_{k+1}|`` with v_k the flow at the
    previous correction point (``previous_velocity`` for the first one: the flow at t_0). Such a flow (a
    current that starts at 0 A, a body the wave has just reached) grows by about itself in every step, so
    Eq. 14's assumption that v stays near v_{k+1} over the next step fails by 100 % or more, and a force
    sized on v_{k+1} drives the next residual (and with it the next correction) the other way.

    The manager applies f_corr,k+1 over [t_{k+1}, t_{k+2}]. 𝒰 uses the force actually applied, so
    energy a cap or the guard kept from being removed is accumulated too.
    """

    nu: float  # ν in [0, 1], Eq. 17
    cap_fraction: float | None  # |f_corr| <= cap_fraction |f|
    cap_force: float | None  # |f_corr| <= cap_force [N]
    dimension: int = 1  # components of f and v
    uncorrected: float = field(default=0.0, init=False)  # 𝒰 [J], Eq. 16
    zeta: float = field(default=0.0, init=False)  # ζ of the step whose correction is being applied [J]
    force: np.ndarray = field(init=False)  # f_corr being applied [N]
    capped: bool = field(default=False, init=False)  # whether a cap limited the force being applied
    withheld: bool = field(default=False, init=False)  # whether the force being applied was withheld (v left rest)
    previous_velocity: np.ndarray | None = None  # v_k [m/s]: the flow at the previous correction point (t_0 first)

    def __post_init__(self) -> None:
        self.force = np.zeros(self.dimension)

    def limit(self, coupling_force: np.ndarray) -> float:
        """Largest admissible |f_corr| [N] for the uncorrected coupling force ``f``."""
        limits = [np.inf]
        if self.cap_fraction is not None:
            limits.append(self.cap_fraction * float(np.linalg.norm(coupling_force)))
        if self.cap_force is not None:
            limits.append(self.cap_force)
        return min(limits)

    def update(self, zeta: float, velocity: np.ndarray, coupling_force: np.ndarray, macro_step: float) -> np.ndarray:
        """Eqs. 15–17 at one correction point; returns f_corr [N] for the next macro-step."""
        v = np.asarray(velocity, dtype=np.float64)
        self.uncorrected += self.zeta + float(self.force.dot(v)) * macro_step
        speed2 = float(v.dot(v))
        previous = self.previous_velocity
        self.previous_velocity = v.copy()
        self.withheld = speed2 > 0.0 and previous is not None and float(previous.dot(previous)) <= AT_REST ** 2 * speed2
        force = np.zeros(self.dimension)
        if speed2 > 0.0 and not self.withheld:
            force = -(zeta + self.nu * self.uncorrected) * v / (speed2 * macro_step)
        magnitude = float(np.linalg.norm(force))
        limit = self.limit(np.asarray(coupling_force, dtype=np.float64))
        self.capped = magnitude > limit
        if self.capped:
            force = force * (limit / magnitude)
        self.zeta, self.force = zeta, force
        return force
