"""G_t(s) and ΔG_c(s) assembled from a LinearModel's bonds (paper 000, Eqs. 4, 12–15, 46)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.perturbation import (
    BondSpecError,
    cosimulated_stiffness,
    interface_perturbation,
    monolithic_stiffness,
)
from zencosim.compensation.linear_model import ForceDisplacementBond

S = [0.3 + 12.0j, -40.0 + 7.0j, 250.0j]  # arbitrary test points [1/s]


def test_monolithic_is_the_dynamic_stiffness_matrix(two_mass):
    model = two_mass(0.1, 1e-3)
    for s in S:
        expected = s**2 * model.M + s * model.C + model.K
        assert monolithic_stiffness(model)(s, D=0.37) == pytest.approx(expected, rel=1e-14)


def test_two_mass_perturbation_is_eq_15(two_mass):
    model = two_mass(0.1, 4e-3)
    hold = InterfaceModel(0, model.macro_step)
    for s in S:
        D = hold.D(s)
        g_c = s * 0.1 + 100.0
        expected = np.array([[0, g_c * (1 - D)], [g_c * (1 - D), g_c * (D**2 - 1)]])
        assert interface_perturbation(model)(s, D) == pytest.approx(expected, rel=1e-14, abs=1e-12)


def test_two_mass_cosimulated_rows_are_eq_13(two_mass):
    # Eq. 13 moved to the left-hand side: row 1 holds the force side, row 2 the motion side.
    model = two_mass(0.1, 1e-3)
    for s in S:
        D = 0.9 - 0.2j  # any value: the identity is algebraic in D
        g_c = s * 0.1 + 100.0
        expected = np.array(
            [
                [s**2 + s * 0.2 + 110.0, -g_c * D],
                [-g_c * D, s**2 + s * 0.1 + 1000.0 + g_c * D**2],
            ]
        )
        assert cosimulated_stiffness(model)(s, D) == pytest.approx(expected, rel=1e-14)


def test_four_mass_perturbation_is_eq_46(four_mass):
    model = four_mass()
    for s in S:
        D = 0.8 + 0.1j
        g_c = s * 0.03 + 300.0
        expected = np.zeros((4, 4), dtype=complex)
        expected[1, 2] = expected[2, 1] = g_c * (1 - D)
        expected[2, 2] = g_c * (D**2 - 1)
        assert interface_perturbation(model)(s, D) == pytest.approx(expected, rel=1e-14, abs=1e-12)


def test_unit_hold_gives_the_monolithic_system(four_mass):
    # §2.2: "Setting D(s) = 1 leads to the monolithic model since ΔG_c(s) = 0".
    model = four_mass()
    for s in S:
        assert interface_perturbation(model)(s, 1.0) == pytest.approx(np.zeros((4, 4)), abs=1e-12)


def test_bonds_add_up(two_mass):
    model = two_mass(0.1, 1e-3)
    doubled = dataclasses.replace(model, bonds=model.bonds * 2)
    for s in S:
        assert interface_perturbation(doubled)(s, 0.7) == pytest.approx(2 * interface_perturbation(model)(s, 0.7))


def test_derivative_matches_central_difference(four_mass):
    model = four_mass()
    hold = InterfaceModel(2, model.macro_step)
    T = cosimulated_stiffness(model)
    h = 1e-4  # [1/s]
    for s in S:
        fd = (T(s + h, hold.D(s + h)) - T(s - h, hold.D(s - h))) / (2 * h)
        assert T.derivative(s, hold.D(s), hold.dD(s)) == pytest.approx(fd, rel=1e-7, abs=1e-7)


@pytest.mark.parametrize("force_dof, motion_dof", [(0, 0), (0, 2), (-1, 1)])
def test_invalid_bonds_are_refused(two_mass, force_dof, motion_dof):
    bond = ForceDisplacementBond("bad", force_dof, motion_dof, 100.0, 0.1)
    model = dataclasses.replace(two_mass(0.1, 1e-3), bonds=(bond,))
    with pytest.raises(BondSpecError, match="two distinct DOFs in 0..1"):
        interface_perturbation(model)
