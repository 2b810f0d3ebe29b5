"""The linear two-mass co-simulation test model of paper 003 (Schweizer, Li, Lu 2015).

Two single-mass oscillators (m_i, c_i, d_i) joined by a rigid link ``x2 - x1 = 0`` whose multiplier
``lambda_c`` acts with ``+lambda_c`` on mass 1 and ``-lambda_c`` on mass 2 (Eq. 4).

Dimensionless form (Eqs. 5, 6): time ``t_bar = t / H``, positions ``x_bar = x / l``, velocities
``v_bar = H v / l``, accelerations ``a_bar = H^2 a / l``, forces ``f_bar = f H^2 / (m1 l)``. This module
uses ``l = 1 m``. Mass 1 then has unit mass and mass 2 the mass ``alpha_m21``; the body parameters are
kept as ``c_bar_i = c_i H^2 / m1`` and ``d_bar_i = d_i H / m1`` for both bodies, which is Eq. 5 with
``c_bar_2 = alpha_c21 c_bar_1`` and ``d_bar_2 = alpha_d21 d_bar_1`` and stays defined at the origin
``c_bar_1 = d_bar_1 = 0`` of the stability maps, where the ratios of Eq. 5 are 0/0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

COUPLING_SIGNS = (1.0, -1.0)  # lambda_c acts with + on mass 1 and - on mass 2 (Eq. 4)


@dataclass(frozen=True)
class DimensionlessTwoMass:
    """The five parameters of the test model in the dimensionless form of Eqs. (5)–(7)."""

    c1_bar: float  # c1 H^2 / m1 [-]
    d1_bar: float  # d1 H / m1 [-]
    alpha_m21: float  # m2 / m1 [-]
    c2_bar: float  # c2 H^2 / m1 = alpha_c21 c1_bar [-]
    d2_bar: float  # d2 H / m1 = alpha_d21 d1_bar [-]

    @classmethod
    def from_eq5(
        cls, c1_bar: float, d1_bar: float, alpha_m21: float, alpha_c21: float, alpha_d21: float
    ) -> DimensionlessTwoMass:
        """The parameters of Eq. (5)."""
        return cls(c1_bar, d1_bar, alpha_m21, alpha_c21 * c1_bar, alpha_d21 * d1_bar)

    @classmethod
    def from_eigenvalues(
        cls,
        lambda_r1: float,
        lambda_i1: float,
        alpha_m21: float,
        alpha_lambda_r21: float,
        alpha_lambda_i21: float,
    ) -> DimensionlessTwoMass:
        """The eigenvalue-based parameters of Eq. (71).

        ``lambda_r1 + i lambda_i1`` is the dimensionless eigenvalue ``H lambda`` of mass 1 alone,
        ``alpha_lambda_r21`` and ``alpha_lambda_i21`` the ratios of the real and imaginary parts of the
        eigenvalue of mass 2 alone to those of mass 1. Inverting Eq. (71) for an oscillator
        ``v' = -(c/m) x - (d/m) v``: ``d/m = -2 lambda_r`` and ``c/m = lambda_r^2 + lambda_i^2``.
        """
        lambda_r2 = alpha_lambda_r21 * lambda_r1
        lambda_i2 = alpha_lambda_i21 * lambda_i1
        return cls(
            c1_bar=lambda_r1**2 + lambda_i1**2,
            d1_bar=-2.0 * lambda_r1,
            alpha_m21=alpha_m21,
            c2_bar=alpha_m21 * (lambda_r2**2 + lambda_i2**2),
            d2_bar=-2.0 * alpha_m21 * lambda_r2,
        )

    @property
    def masses(self) -> tuple[float, float]:
        """Dimensionless masses ``(1, alpha_m21)``."""
        return (1.0, self.alpha_m21)

    @property
    def stiffnesses(self) -> tuple[float, float]:
        return (self.c1_bar, self.c2_bar)

    @property
    def dampings(self) -> tuple[float, float]:
        return (self.d1_bar, self.d2_bar)


@dataclass(frozen=True)
class TwoMassOscillator:
    """The test model with physical parameters (Eq. 4), e.g. the §3.7 convergence model."""

    m1: float  # mass 1 [kg]
    m2: float  # mass 2 [kg]
    c1: float  # stiffness of mass 1 [N/m]
    c2: float  # stiffness of mass 2 [N/m]
    d1: float  # damping of mass 1 [N s/m]
    d2: float  # damping of mass 2 [N s/m]

    def dimensionless(self, macro_step: float) -> DimensionlessTwoMass:
        """The parameters of Eq. (5) for the macro-step size ``H = macro_step`` [s]."""
        return DimensionlessTwoMass(
            c1_bar=self.c1 * macro_step**2 / self.m1,
            d1_bar=self.d1 * macro_step / self.m1,
            alpha_m21=self.m2 / self.m1,
            c2_bar=self.c2 * macro_step**2 / self.m1,
            d2_bar=self.d2 * macro_step / self.m1,
        )

    def monolithic_solution(
        self, position_0: float, velocity_0: float, times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Analytic solution of the index-3 DAE (4): ``(x, v, a, lambda_c)`` at ``times`` [s].

        With ``x1 = x2 = x`` the masses move as one: ``(m1 + m2) a = -(c1 + c2) x - (d1 + d2) v``, and
        the multiplier follows from the first row of Eq. (4): ``lambda_c = m1 a + c1 x + d1 v``.
        ``times`` may be negative (the history that a Lagrange predictor of degree k needs at T_0).
        The state matrix is diagonalised, so the model must not be critically damped.
        """
        mass = self.m1 + self.m2
        A = np.array([[0.0, 1.0], [-(self.c1 + self.c2) / mass, -(self.d1 + self.d2) / mass]])
        eigenvalues, V = np.linalg.eig(A)
        if np.isclose(eigenvalues[0], eigenvalues[1]):
            raise ValueError("the monolithic two-mass model is critically damped; its state matrix is not diagonalisable")
        modal_0 = np.linalg.solve(V, np.array([position_0, velocity_0], dtype=complex))
        times = np.asarray(times, dtype=float)
        state = (V @ (modal_0[:, None] * np.exp(np.outer(eigenvalues, times)))).real
        position, velocity = state
        acceleration = A[1, 0] * position + A[1, 1] * velocity
        multiplier = self.m1 * acceleration + self.c1 * position + self.d1 * velocity
        return position, velocity, acceleration, multiplier
