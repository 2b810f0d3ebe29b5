"""Coupling laws of the implicit predictor/corrector co-simulation methods of paper 003, §2.

One macro-step T_N -> T_{N+1} of every method:

1. predictor: integrate both subsystems with the coupling variables extrapolated from
   ``e_N, ..., e_{N-k}`` (Eq. 9);
2. coupling law: from the predicted outputs at T_{N+1}, their derivatives w.r.t. the coupling
   variables at T_{N+1} and the predicted coupling variables, compute corrected coupling variables
   ``e_{N+1}`` (this module);
3. corrector: integrate again from T_N (rollback) with the interpolation polynomial through
   ``e_{N+1}, e_N, ..., e_{N-k+1}`` (Eq. 11);
4. projection method only: project positions and velocities onto the constraint (Eq. 30).

The laws are pure functions of numbers (a runtime manager calls them with real subsystem outputs)
and are linear in the predicted outputs and the coupling history, so they also accept arrays with a
trailing axis: the recurrence builder passes one column per recurrence state.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from zencosim.compensation.implicit.decompositions import (
    Decomposition,
    LinearisedCouplingConditions,
    resolve_decomposition,
)
from zencosim.compensation.lagrange_polynomials import extrapolation_weights


@dataclass(frozen=True)
class Baumgarte:
    """Baumgarte stabilisation (§2.1.1, §2.2.1): zero ``g_pos + beta g_vel + gamma g_acc`` (Eqs. 7c, 16, 43).

    ``beta`` and ``gamma`` are in the time unit of the outputs: the dimensionless ``beta_bar``,
    ``gamma_bar`` of the recurrence, or ``beta = beta_bar H`` [s] and ``gamma = gamma_bar H^2`` [s^2]
    with outputs in SI units. ``gamma = 0`` gives the index-2 and ``beta = gamma = 0`` the index-3
    formulation (§3.4, §3.5). The default is the paper's ``mu_bar = 1``.
    """

    beta: float = 2.0
    gamma: float = 1.0
    projects_states: ClassVar[bool] = False

    @classmethod
    def from_mu(cls, mu: float, index: int = 1) -> Baumgarte:
        """The one-parameter form ``beta = 2 mu``, ``gamma = mu^2`` (§3.1.1) on index-1 level; index 2
        keeps ``beta = 2 mu`` with ``gamma = 0`` (§3.4.1), index 3 has ``beta = gamma = 0`` (§3.5)."""
        if index not in (1, 2, 3):
            raise ValueError(f"Baumgarte index must be 1, 2 or 3; got {index!r}")
        return cls(beta=2.0 * mu if index < 3 else 0.0, gamma=mu**2 if index == 1 else 0.0)

    def correct(self, predicted_coupling: np.ndarray, conditions: LinearisedCouplingConditions) -> np.ndarray:
        return conditions.root(predicted_coupling, (1.0, self.beta, self.gamma))

    def in_macro_step_units(self, macro_step: float) -> Baumgarte:
        """``beta_bar = beta / H``, ``gamma_bar = gamma / H^2`` (§2.1.1) for parameters given in seconds."""
        return Baumgarte(self.beta / macro_step, self.gamma / macro_step**2)


@dataclass(frozen=True)
class WeightedMultiplier:
    """Weighted multiplier approach (§2.1.2, §2.2.2): the weighted mean of the coupling variables that
    satisfy the constraint on position, velocity and acceleration level (Eqs. 24–27, 50–53).

    ``b = 0`` gives the index-2 and ``a = b = 0`` the index-3 formulation (§3.4.2, §3.5). Levels
    with weight 0 are not solved (they would not change the mean).

    Reading of the extracted text: Eqs. (24) and (27) show the acceleration-level derivative as
    ``d v2'* / d lambda'*`` evaluated at ``lambda'^p``; taken as the derivative w.r.t. the coupling
    force ``lambda*_{c,N+1}`` at ``lambda^p_{c,N+1}``, as in Eqs. (13) and (49).
    """

    a: float = 1.0
    b: float = 1.0
    projects_states: ClassVar[bool] = False

    def correct(self, predicted_coupling: np.ndarray, conditions: LinearisedCouplingConditions) -> np.ndarray:
        level_weights = (1.0, self.a, self.b)
        weighted_sum = sum(
            weight * conditions.root(predicted_coupling, tuple(np.eye(3)[level]))
            for level, weight in enumerate(level_weights)
            if weight != 0.0
        )
        return weighted_sum / sum(level_weights)

    def in_macro_step_units(self, macro_step: float) -> WeightedMultiplier:
        """``a`` and ``b`` weigh coupling variables, not residuals: they do not depend on the time unit."""
        return self


@dataclass(frozen=True)
class Projection:
    """Projection method (§2.1.3, §2.2.3, §2.3.1): the constraint on acceleration level (Eqs. 27, 52, 66),
    followed by the projection step of Eq. (30) (``project_onto_constraint``)."""

    projects_states: ClassVar[bool] = True

    def correct(self, predicted_coupling: np.ndarray, conditions: LinearisedCouplingConditions) -> np.ndarray:
        return conditions.root(predicted_coupling, (0.0, 0.0, 1.0))

    def in_macro_step_units(self, macro_step: float) -> Projection:
        return self


CouplingMethod = Baumgarte | WeightedMultiplier | Projection

METHODS: dict[str, type] = {
    "baumgarte": Baumgarte,
    "weighted-multiplier": WeightedMultiplier,
    "projection": Projection,
}

# §2.3: Baumgarte and weighted multiplier would need the motion prescribed on position level
# (a quadratic x_tilde), which constant and linear polynomials cannot give; the paper treats only
# projection for displacement/displacement.
_METHODS_OF_DECOMPOSITION = {
    "force-force": ("baumgarte", "weighted-multiplier", "projection"),
    "force-displacement": ("baumgarte", "weighted-multiplier", "projection"),
    "displacement-displacement": ("projection",),
}


def resolve_method(method: str | CouplingMethod, **options: float) -> CouplingMethod:
    """A coupling method: a registered name (``METHODS``) with its options, or an instance."""
    if not isinstance(method, str):
        if options:
            raise ValueError("method options are given with a method instance; put them in the instance")
        return method
    try:
        method_class = METHODS[method]
    except KeyError:
        raise ValueError(f"unknown coupling method {method!r}; expected one of {', '.join(METHODS)}") from None
    return method_class(**options)


def method_name(method: CouplingMethod) -> str:
    """The registry name of a method instance."""
    return next(name for name, cls in METHODS.items() if isinstance(method, cls))


def check_supported(method: CouplingMethod, decomposition: Decomposition) -> None:
    """Raise ValueError for a method the paper does not define on this decomposition (§2.3)."""
    supported = _METHODS_OF_DECOMPOSITION[decomposition.name]
    if method_name(method) not in supported:
        raise ValueError(
            f"method {method_name(method)!r} is not defined for the {decomposition.name} decomposition "
            f"(paper 003 §2.3); expected one of {', '.join(supported)}"
        )


def corrected_coupling(
    method: CouplingMethod,
    decomposition: str | Decomposition,
    coupling_history: np.ndarray,
    predicted_outputs: np.ndarray,
    output_sensitivity: np.ndarray,
) -> np.ndarray:
    """Corrected coupling variables ``e_{N+1}`` at T_{N+1}: step 2 of every method.

    ``coupling_history`` (k + 1, n_e, ...): ``e_N, e_{N-1}, ..., e_{N-k}``, newest first; its
    length sets the degree k of the predictor. ``predicted_outputs`` (2, 4, ...): position, velocity,
    acceleration and coupling force of mass 1 and mass 2 at T_{N+1} from the predictor run.
    ``output_sensitivity`` (2, 4, n_e): their derivatives w.r.t. ``e*_{N+1}``, the value at T_{N+1} of
    the corrector polynomial (Eqs. 13, 39, 63; constant for the linear model). Returns (n_e, ...).
    A joint with ``d`` axes (a point in the plane) passes outputs (2, 4, d) and sensitivities
    (2, 4, d, n_e); its conditions hold on every axis (``LinearisedCouplingConditions``).

    The corrector polynomial through ``e*_{N+1}, e_N, ..., e_{N-k+1}`` equals the predictor polynomial
    when ``e*_{N+1} = e^p_{N+1}``, so the predictor outputs are the conditions at ``e^p`` (Eq. 15).
    Reading of the extracted text: Eqs. (37) and (61) mark some older sampling points of the corrector
    polynomial with a star; they are taken as the corrected values of the previous macro-steps, as in
    Eq. (11), since no other values exist at those points.
    """
    decomposition = resolve_decomposition(decomposition)
    coupling_history = np.asarray(coupling_history, dtype=float)
    predicted_coupling = np.tensordot(extrapolation_weights(len(coupling_history) - 1), coupling_history, axes=1)
    conditions = decomposition.linearised_conditions(np.asarray(predicted_outputs), np.asarray(output_sensitivity))
    return method.correct(predicted_coupling, conditions)


def project_onto_constraint(
    positions: np.ndarray, velocities: np.ndarray, masses: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Projection step, Eq. (30): the mass-weighted means ``(m1 x1 + m2 x2) / (m1 + m2)`` of the
    positions and of the velocities of the two masses (``alpha_m21 = m2 / m1``)."""
    m1, m2 = masses
    return (m1 * positions[0] + m2 * positions[1]) / (m1 + m2), (m1 * velocities[0] + m2 * velocities[1]) / (m1 + m2)
