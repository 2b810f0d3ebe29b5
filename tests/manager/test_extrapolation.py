"""Lagrange extrapolation (order 0/1/2) is exact on polynomials up to its order, and only those."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.scheme.extrapolation import evaluate, extrapolation_matrix, lagrange_matrix

coefficient = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(order=st.integers(0, 2), coefficients=st.lists(coefficient, min_size=3, max_size=3),
       step_us=st.integers(10, 10_000), offset_steps=st.integers(0, 9), tau_fraction=st.floats(0.0, 10.0))
def test_exact_on_polynomials_up_to_the_order(order, coefficients, step_us, offset_steps, tau_fraction):
    step_ns = step_us * 1000
    offset_ns = offset_steps * step_ns // 10
    true = np.polynomial.Polynomial(coefficients[:order + 1])  # degree <= order, in absolute time [s]
    times = np.array([(-offset_ns - (order - k) * step_ns) * 1e-9 for k in range(order + 1)])
    P = extrapolation_matrix(order + 1, step_ns, offset_ns)
    fitted = P @ true(times)
    tau = tau_fraction * step_ns * 1e-9
    scale = 1.0 + np.sum(np.abs(coefficients[:order + 1]) * (tau + (order + 1) * step_ns * 1e-9) ** np.arange(order + 1))
    # the Vandermonde inverse amplifies round-off by its condition number (~(1 + 2/h)^2 for SOH)
    assert evaluate(fitted.reshape(-1, 1), 0, tau) == pytest.approx(true(tau), abs=1e-9 * scale)


@pytest.mark.parametrize("order", [0, 1])
def test_not_exact_one_degree_above_the_order(order):
    times = tuple(-k * 1e-3 for k in range(order, -1, -1))
    true = np.polynomial.Polynomial([0.0] * (order + 1) + [1.0])  # degree order + 1
    fitted = lagrange_matrix(times) @ true(np.array(times))
    assert abs(evaluate(fitted.reshape(-1, 1), 0, 1e-3) - true(1e-3)) > 1e-10


def test_repeated_sample_times_are_refused():
    with pytest.raises(ValueError, match="distinct"):
        lagrange_matrix((0.0, 0.0))
