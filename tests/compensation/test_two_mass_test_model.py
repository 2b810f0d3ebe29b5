"""The test model's parameter sets (paper 003, Eqs. 5 and 71)."""
from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from zencosim.compensation.implicit.two_mass_test_model import DimensionlessTwoMass, TwoMassOscillator


def _eigenvalue(mass, stiffness, damping):
    """Eigenvalue with positive imaginary part of m x'' + d x' + c x = 0."""
    eigenvalues = np.roots([mass, damping, stiffness])
    return eigenvalues[np.argmax(eigenvalues.imag)]


def test_eigenvalue_parameters_give_the_requested_eigenvalues():
    """Eq. (71) inverted: each mass alone has the eigenvalue lambda_r + i lambda_i asked for
    (mass 2: the ratios times those of mass 1). Rounding of np.roots: 1e-12."""
    model = DimensionlessTwoMass.from_eigenvalues(-0.3, 1.2, 2.5, 1.5, 0.7)
    masses, stiffnesses, dampings = model.masses, model.stiffnesses, model.dampings
    assert _eigenvalue(masses[0], stiffnesses[0], dampings[0]) == pytest.approx(-0.3 + 1.2j, abs=1e-12)
    assert _eigenvalue(masses[1], stiffnesses[1], dampings[1]) == pytest.approx(-0.45 + 0.84j, abs=1e-12)


def test_eq5_parameters_match_physical_parameters():
    """Eq. (5): c1_bar = c1 H^2 / m1, d1_bar = d1 H / m1 and the ratios m2/m1, c2/c1, d2/d1."""
    physical = TwoMassOscillator(m1=1.0, m2=2.0, c1=1000.0, c2=500.0, d1=10.0, d2=30.0)
    from_ratios = DimensionlessTwoMass.from_eq5(c1_bar=1000.0 * 0.01**2, d1_bar=0.1, alpha_m21=2.0, alpha_c21=0.5, alpha_d21=3.0)
    assert astuple(physical.dimensionless(0.01)) == pytest.approx(astuple(from_ratios), rel=1e-14)
