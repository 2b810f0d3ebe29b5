"""D(s) of the co-simulation interface: exact, rational (Padé) and state-space forms."""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.interface import (
    InterfaceModel,
    InterfaceSpecError,
    lagrange_extrapolation_basis,
)

T_S = 1e-3
# Points of the s-plane [1/s] covering both branches of the exact evaluation (|sT| < 1 and >= 1)
# and both half planes, away from the poles of the Padé form (|sT| ~ 8–10 for order 6).
S_POINTS = np.array([10j, 0.1 + 33.3j, 900j, 3000 + 2000j, -1500 + 500j, -2000 + 3000j])


@pytest.mark.parametrize("order", [0, 1, 2])
def test_basis_is_lagrange_on_past_samples(order):
    a = np.array([[float(c) for c in row] for row in lagrange_extrapolation_basis(order)])
    for m in range(order + 1):
        values = [np.polyval(a[m][::-1], -l) for l in range(order + 1)]
        assert values == pytest.approx([1.0 if l == m else 0.0 for l in range(order + 1)], abs=1e-15)


def test_zoh_is_eq_2():
    z = S_POINTS * T_S
    assert InterfaceModel(0, T_S).D(S_POINTS) == pytest.approx((1 - np.exp(-z)) / z, rel=1e-13)


def test_foh_is_the_predictive_first_order_hold():
    z = S_POINTS * T_S
    expected = (1 + z) * (1 - np.exp(-z)) ** 2 / z**2
    assert InterfaceModel(1, T_S).D(S_POINTS) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_unit_static_gain_and_order_of_contact(order):
    # D(s) -> 1 as s -> 0, and D = 1 + O(z^{q+1}): extrapolation of order q is exact for
    # polynomials of degree q. Slope from z = 1e-2 j and 5e-3 j; next term is O(z), tolerance 0.02.
    hold = InterfaceModel(order, T_S)
    assert hold.D(1e-9j / T_S) == pytest.approx(1.0, abs=1e-9)
    e1, e2 = (abs(hold.D(z / T_S) - 1.0) for z in (1e-2j, 5e-3j))
    assert np.log2(e1 / e2) == pytest.approx(order + 1, abs=0.02)


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("pade_order", range(1, 11))
def test_rational_form_has_unit_static_gain(order, pade_order):
    for hold in (InterfaceModel(order, T_S), InterfaceModel(order, T_S, send_delay=2e-4, receive_delay=3e-4)):
        assert hold.rational(pade_order)(0.0) == pytest.approx(1.0, abs=1e-12)


def test_exact_evaluation_is_continuous_across_the_series_branch():
    hold = InterfaceModel(2, 1.0)
    for direction in (1, 1j, -1, np.exp(0.7j)):
        inside, outside = hold._evaluate(direction * (1 - 1e-9)), hold._evaluate(direction * (1 + 1e-9))
        assert inside[0] == pytest.approx(outside[0], rel=1e-8)
        assert inside[1] == pytest.approx(outside[1], rel=1e-8)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_derivative_matches_central_difference(order):
    hold = InterfaceModel(order, T_S, send_delay=1e-4)
    h = 1e-3  # [1/s]; central difference error ~ h^2 |D'''| T^3 ~ 1e-15
    fd = (hold.D(S_POINTS + h) - hold.D(S_POINTS - h)) / (2 * h)
    assert hold.dD(S_POINTS) == pytest.approx(fd, rel=1e-6, abs=1e-12)


def test_delays_multiply_by_the_exponential():
    plain, delayed = InterfaceModel(1, T_S), InterfaceModel(1, T_S, send_delay=2e-4, receive_delay=3e-4)
    assert delayed.D(S_POINTS) == pytest.approx(plain.D(S_POINTS) * np.exp(-S_POINTS * 5e-4), rel=1e-13)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_rational_form_matches_exact_where_pade_is_accurate(order):
    # Order 6: the hold error is O(z^{13-(q+1)}); at |z| <= 0.5 that is below 1e-9.
    hold = InterfaceModel(order, T_S, receive_delay=2e-4)
    s = np.array([10j, 33.3j, 200 + 300j, -100 + 400j, 500j])
    assert hold.rational(6)(s) == pytest.approx(hold.D(s), rel=1e-9)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_realization_reproduces_the_rational_form(order):
    rational = InterfaceModel(order, T_S, send_delay=1e-4).rational(6)
    A, B, C = rational.realization()
    for s in S_POINTS:
        assert C @ np.linalg.solve(s * np.eye(len(B)) - A, B) == pytest.approx(rational(s), rel=1e-9)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(extrapolation_order=3, macro_step=T_S), "extrapolation order"),
        (dict(extrapolation_order=0, macro_step=0.0), "macro step"),
        (dict(extrapolation_order=0, macro_step=T_S, send_delay=-1e-4), "send_delay"),
    ],
)
def test_invalid_interfaces_are_refused(kwargs, message):
    with pytest.raises(InterfaceSpecError, match=message):
        InterfaceModel(**kwargs)
