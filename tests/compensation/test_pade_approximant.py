"""Padé approximant of e^{-x} (paper 000, Eqs. 16–17)."""
from __future__ import annotations

from decimal import Decimal, localcontext
from fractions import Fraction
from math import log2

import pytest

from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.pade import MAX_PADE_ORDER, PadeOrderError, pade_coefficients


def test_first_order_coefficients_are_the_bilinear_approximant():
    p, q = pade_coefficients(1)
    assert p == (1, Fraction(-1, 2)) and q == (1, Fraction(1, 2))


def _error(order: int, x: Fraction) -> Decimal:
    """|e^{-x} - P(x)/Q(x)| in 120-digit decimal arithmetic (double precision cannot see 1e-40)."""
    p, q = pade_coefficients(order)
    ratio = sum(c * x**i for i, c in enumerate(p)) / sum(c * x**i for i, c in enumerate(q))
    with localcontext() as ctx:
        ctx.prec = 120
        return abs((-Decimal(x.numerator) / Decimal(x.denominator)).exp() - Decimal(ratio.numerator) / Decimal(ratio.denominator))


@pytest.mark.parametrize("order", range(1, MAX_PADE_ORDER + 1))
def test_error_slope_is_two_n_plus_one(order):
    # Halving x from 0.02 divides the error by 2^(2n+1); the next term of the error series
    # changes the slope by O(x) ~ 0.02, hence the tolerance 0.05.
    x = Fraction(1, 50)
    slope = log2(_error(order, x) / _error(order, x / 2))
    assert slope == pytest.approx(2 * order + 1, abs=0.05)


@pytest.mark.parametrize("order", [0, MAX_PADE_ORDER + 1, 2.0, True])
def test_orders_outside_one_to_ten_are_refused(order):
    with pytest.raises(PadeOrderError, match="Padé order"):
        pade_coefficients(order)


def test_interface_refuses_order_eleven():
    with pytest.raises(PadeOrderError, match="between 1 and 10"):
        InterfaceModel(extrapolation_order=0, macro_step=1e-3).rational(11)
