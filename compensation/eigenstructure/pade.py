"""Diagonal Padé approximant of the delay ``e^{-x}`` (paper 000, Eqs. 16–17).

``e^{-x} ≈ P(x) / Q(x)`` with ``P(x) = Σ p_i x^i`` and ``Q(x) = Σ q_i x^i``, ``i = 0..n_p``:

    q_i = (2 n_p - i)! n_p! / ((2 n_p)! i! (n_p - i)!),    p_i = (-1)^i q_i

(the paper prints the range ``i = 1..n_p``; ``i = 0`` gives ``p_0 = q_0 = 1`` and is part of the
approximant). The error is ``e^{-x} - P/Q = O(x^{2 n_p + 1})``. Only the diagonal case
``m_p = n_p`` is provided (the paper's "common choice"). The order is limited to
``n_p <= 10`` as the paper recommends (high orders cluster the poles of ``Q``, which then become
very sensitive to round-off) — a larger order is refused, not clipped.

The coefficients are exact rationals so that callers can do exact polynomial algebra with them
(``compensation.eigenstructure.interface`` cancels a factor ``x^{q+1}`` exactly).
"""
from __future__ import annotations

from fractions import Fraction
from math import factorial

MAX_PADE_ORDER = 10


class PadeOrderError(ValueError):
    """The requested Padé order is outside ``1..MAX_PADE_ORDER``."""


def check_pade_order(order: int) -> int:
    """Return ``order`` if it is an integer in ``1..MAX_PADE_ORDER``; raise ``PadeOrderError`` otherwise."""
    if isinstance(order, bool) or not isinstance(order, int):
        raise PadeOrderError(f"Padé order must be an integer; got {order!r}")
    if not 1 <= order <= MAX_PADE_ORDER:
        raise PadeOrderError(
            f"Padé order must be between 1 and {MAX_PADE_ORDER} (paper 000 recommends n_p <= 10: "
            f"higher orders give clustered, round-off-sensitive poles); got {order}"
        )
    return order


def pade_coefficients(order: int) -> tuple[tuple[Fraction, ...], tuple[Fraction, ...]]:
    """Exact ``(p, q)`` of Eq. 17, ascending powers of ``x``, each of length ``order + 1``."""
    n = check_pade_order(order)
    q = tuple(
        Fraction(factorial(2 * n - i) * factorial(n), factorial(2 * n) * factorial(i) * factorial(n - i))
        for i in range(n + 1)
    )
    p = tuple((-1) ** i * qi for i, qi in enumerate(q))
    return p, q
