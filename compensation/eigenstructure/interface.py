"""Transfer function ``D(s)`` of the co-simulation interface (paper 000, Eqs. 1–2, 16–17).

The manager samples a signal ``y`` at the communication points ``t_k = k T_s`` and the receiver
integrates over ``[t_k, t_k + T_s]`` with the Lagrange polynomial of order ``q`` through the last
``q + 1`` samples ``y(t_k), y(t_k - T_s), ..., y(t_k - q T_s)`` (ZOH ``q = 0``, FOH ``q = 1``,
SOH ``q = 2``). With ``τ = (t - t_k) / T_s`` the held signal is

    y*(t_k + τ T_s) = Σ_{m=0}^{q} ℓ_m(τ) y(t_k - m T_s),   0 <= τ < 1,

``ℓ_m`` the Lagrange basis on the nodes ``τ = 0, -1, ..., -q``.

Derivation of ``D(s)``. A unit sample at ``t = 0`` is used as the ``m``-th past sample on the
interval ``[m T_s, (m+1) T_s)``, so the impulse response of the hold is
``h(t) = ℓ_m(t/T_s - m)`` there and, with ``z = s T_s``,

    H(s) = Σ_m e^{-m z} T_s ∫_0^1 ℓ_m(τ) e^{-z τ} dτ.

The sampler is modelled as an impulse train of weight ``T_s`` (the model behind Eq. 2: the gain on
the fundamental of a signal, aliases neglected, valid well below the Nyquist frequency
``π / T_s``), which gives

    D(s) = H(s) / T_s = Σ_{m=0}^{q} e^{-m z} Σ_n a_{m,n} I_n(z),   I_n(z) = ∫_0^1 τ^n e^{-z τ} dτ,

with ``ℓ_m(τ) = Σ_n a_{m,n} τ^n``. For ``q = 0`` this is Eq. 2, ``(1 - e^{-z}) / z``; for ``q = 1``
it is the classic predictive first-order hold ``(1 + z) (1 - e^{-z})^2 / z^2``. ``D(0) = 1``
(the basis is a partition of unity) and ``D(s) = 1 + O(z^{q+1})``: extrapolation of order ``q``
is exact for polynomials of degree ``q``. Send and receive latencies ``t_i``, ``t_r`` multiply
``D`` by ``e^{-s (t_i + t_r)}``.

Rational form (Eqs. 16–17). ``I_n(z) = n! z^{-(n+1)} (1 - e^{-z} e_n(z))`` with
``e_n(z) = Σ_{j<=n} z^j / j!``, so ``D`` is a polynomial in ``E = e^{-z}`` over ``z^{q+1}``.
Every ``E`` is replaced by the Padé approximant ``P(z) / Q(z)`` (so ``e^{-m z}`` becomes
``(P/Q)^m``, not a Padé approximant of ``e^{-m z}``), the factor ``z^{q+1}`` cancels exactly (the
arithmetic is done in exact rationals), and a delay ``e^{-s t_d}`` is replaced by
``P(s t_d) / Q(s t_d)`` of the same order. The result is strictly proper.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np
from numpy.polynomial import polynomial as npoly

from zencosim.compensation.eigenstructure.pade import pade_coefficients

EXTRAPOLATION_ORDERS = {0: "ZOH", 1: "FOH", 2: "SOH"}

_SERIES_RADIUS = 1.0  # |z| below which I_n(z) is summed as a series (the recursion cancels there)
_SERIES_TERMS = 30  # |z|^30 / 30! < 1e-32 for |z| < 1


class InterfaceSpecError(ValueError):
    """An interface model was given an invalid extrapolation order, macro step or delay."""


@lru_cache(maxsize=None)
def lagrange_extrapolation_basis(order: int) -> tuple[tuple[Fraction, ...], ...]:
    """Exact ``a[m][n]`` with ``ℓ_m(τ) = Σ_n a[m][n] τ^n`` on the nodes ``τ = 0, -1, ..., -order``."""
    nodes = [Fraction(-m) for m in range(order + 1)]
    basis = []
    for m, node_m in enumerate(nodes):
        coeffs = [Fraction(1)]
        for l, node_l in enumerate(nodes):
            if l != m:
                coeffs = _poly_mul(coeffs, [-node_l / (node_m - node_l), 1 / (node_m - node_l)])
        basis.append(tuple(coeffs))
    return tuple(basis)


def _poly_mul(a: list[Fraction], b: list[Fraction]) -> list[Fraction]:
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, ai in enumerate(a):
        for j, bj in enumerate(b):
            out[i + j] += ai * bj
    return out


def _poly_add(a: list[Fraction], b: list[Fraction]) -> list[Fraction]:
    out = [Fraction(0)] * max(len(a), len(b))
    for i, ai in enumerate(a):
        out[i] += ai
    for i, bi in enumerate(b):
        out[i] += bi
    return out


def _poly_pow(a: list[Fraction], power: int) -> list[Fraction]:
    out = [Fraction(1)]
    for _ in range(power):
        out = _poly_mul(out, a)
    return out


def _moment_integrals(z: np.ndarray, n_max: int) -> np.ndarray:
    """``I_n(z) = ∫_0^1 τ^n e^{-z τ} dτ`` for ``n = 0..n_max``; shape ``(n_max + 1,) + z.shape``.

    A series ``Σ_j (-z)^j / (j! (n + j + 1))`` for ``|z| < 1`` and the recursion
    ``I_0 = (1 - e^{-z}) / z``, ``I_n = (n I_{n-1} - e^{-z}) / z`` elsewhere (it amplifies
    round-off by at most ``n / |z| <= n_max`` there).
    """
    shape = np.shape(z)
    z = np.atleast_1d(np.asarray(z, dtype=complex))
    out = np.empty((n_max + 1,) + z.shape, dtype=complex)
    small = np.abs(z) < _SERIES_RADIUS
    zs = z[small]
    j = np.arange(_SERIES_TERMS)
    inv_fact = np.array([1.0 / factorial(int(k)) for k in j])
    powers = (-zs[..., None]) ** j * inv_fact
    zl = z[~small]
    e = np.exp(-zl)
    previous = (1.0 - e) / zl
    for n in range(n_max + 1):
        out[n][small] = powers @ (1.0 / (n + j + 1.0))
        if n > 0:
            previous = (n * previous - e) / zl
        out[n][~small] = previous
    return out.reshape((n_max + 1,) + shape)


@lru_cache(maxsize=None)
def _hold_polynomials(order: int, pade_order: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Ascending coefficients in ``z`` of the Padé form of the hold (without latency).

    ``num = Σ_m Σ_n a_{m,n} n! z^{q-n} P^m Q^{q-m} (Q - P e_n) / z^{q+1}``, ``den = Q^{q+1}``,
    computed in exact rationals (cached: about 7 ms for SOH).
    """
    p, q_coeffs = pade_coefficients(pade_order)
    P, Q = list(p), list(q_coeffs)
    num: list[Fraction] = [Fraction(0)]
    for m, row in enumerate(lagrange_extrapolation_basis(order)):
        PmQ = _poly_mul(_poly_pow(P, m), _poly_pow(Q, order - m))
        for n, a_mn in enumerate(row):
            e_n = [Fraction(1, factorial(j)) for j in range(n + 1)]
            bracket = _poly_add(Q, [-c for c in _poly_mul(P, e_n)])
            term = _poly_mul(PmQ, bracket)
            shifted = [Fraction(0)] * (order - n) + [a_mn * factorial(n) * c for c in term]
            num = _poly_add(num, shifted)
    if any(c != 0 for c in num[: order + 1]):  # guaranteed by 2 n_p >= q; checked, not assumed
        raise ArithmeticError(f"z^{order + 1} does not divide the hold numerator for Padé order {pade_order}")
    num = num[order + 1 :]
    while len(num) > 1 and num[-1] == 0:
        num.pop()
    den = _poly_pow(Q, order + 1)
    return tuple(float(c) for c in num), tuple(float(c) for c in den)


@dataclass(frozen=True)
class RationalTransfer:
    """``D(s) ≈ num(z) / den(z)``, ``z = s * time_scale``; coefficients in ascending powers of ``z``."""

    num: np.ndarray
    den: np.ndarray
    time_scale: float  # T_s [s]

    def __call__(self, s) -> np.ndarray:
        z = np.asarray(s, dtype=complex) * self.time_scale
        return npoly.polyval(z, self.num) / npoly.polyval(z, self.den)

    def poles(self) -> np.ndarray:
        """Poles in ``s`` [1/s]."""
        return npoly.polyroots(self.den) / self.time_scale

    def realization(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Controllable canonical (companion) ``(A, B, C)`` with ``D(s) = C (sI - A)^{-1} B``, s in [1/s].

        The variable is first scaled, ``z = ρ w`` with ``ρ = |den_0 / den_n|^{1/n}`` (the geometric
        mean of the pole magnitudes), so that the companion coefficients are of order one.
        Requires a strictly proper transfer function (every hold is one).
        """
        n = len(self.den) - 1
        if len(self.num) > n:
            raise ValueError(
                f"realization needs a strictly proper transfer function; numerator degree "
                f"{len(self.num) - 1} is not below denominator degree {n}"
            )
        rho = abs(self.den[0] / self.den[-1]) ** (1.0 / n)
        den_w = self.den * rho ** np.arange(n + 1)
        num_w = self.num * rho ** np.arange(len(self.num))
        num_w, den_w = num_w / den_w[-1], den_w / den_w[-1]
        A = np.zeros((n, n))
        A[:-1, 1:] = np.eye(n - 1)
        A[-1, :] = -den_w[:-1]
        B = np.zeros(n)
        B[-1] = 1.0
        C = np.zeros(n)
        C[: len(num_w)] = num_w
        # z = ρ w and z = s T_s: (A, B) scale by ρ / T_s, C is unchanged.
        scale = rho / self.time_scale
        return A * scale, B * scale, C


@dataclass(frozen=True)
class InterfaceModel:
    """``D(s)`` of one crossing of the interface: Lagrange extrapolation of order ``q`` plus latencies."""

    extrapolation_order: int  # q: 0 ZOH, 1 FOH, 2 SOH
    macro_step: float  # T_s [s]
    send_delay: float = 0.0  # t_i [s]
    receive_delay: float = 0.0  # t_r [s]

    def __post_init__(self):
        if self.extrapolation_order not in EXTRAPOLATION_ORDERS:
            raise InterfaceSpecError(
                f"extrapolation order must be one of {sorted(EXTRAPOLATION_ORDERS)} "
                f"(ZOH, FOH, SOH); got {self.extrapolation_order!r}"
            )
        if not self.macro_step > 0.0:
            raise InterfaceSpecError(f"macro step must be positive [s]; got {self.macro_step!r}")
        for name in ("send_delay", "receive_delay"):
            if not getattr(self, name) >= 0.0:
                raise InterfaceSpecError(f"{name} must be non-negative [s]; got {getattr(self, name)!r}")

    @property
    def delay(self) -> float:
        """Total latency ``t_i + t_r`` [s]."""
        return self.send_delay + self.receive_delay

    @property
    def _basis(self) -> np.ndarray:
        a = lagrange_extrapolation_basis(self.extrapolation_order)
        return np.array([[float(c) for c in row] for row in a])

    def D(self, s) -> np.ndarray:
        """Exact ``D(s)`` (complex evaluation of the exponentials)."""
        return self._evaluate(s)[0]

    def dD(self, s) -> np.ndarray:
        """Exact ``dD/ds`` [s], from ``dI_n/dz = -I_{n+1}``."""
        return self._evaluate(s)[1]

    def _evaluate(self, s) -> tuple[np.ndarray, np.ndarray]:
        q, T = self.extrapolation_order, self.macro_step
        s = np.asarray(s, dtype=complex)
        z = s * T
        a = self._basis
        I = _moment_integrals(z, q + 1)
        hold = np.zeros_like(z)
        dhold_dz = np.zeros_like(z)
        for m in range(q + 1):
            e_m = np.exp(-m * z)
            for n in range(q + 1):
                hold = hold + a[m, n] * e_m * I[n]
                dhold_dz = dhold_dz + a[m, n] * e_m * (-m * I[n] - I[n + 1])
        latency = np.exp(-s * self.delay)
        D = hold * latency
        dD = T * dhold_dz * latency - self.delay * D
        return D, dD

    def rational(self, pade_order: int) -> RationalTransfer:
        """``D(s)`` with every exponential replaced by its Padé approximant of order ``pade_order``.

        Raises ``PadeOrderError`` for an order outside ``1..10``.
        """
        num_f, den_f = (np.array(c) for c in _hold_polynomials(self.extrapolation_order, pade_order))
        if self.delay > 0.0:
            p, q = pade_coefficients(pade_order)
            r = self.delay / self.macro_step  # e^{-s t_d} = e^{-r z}
            powers = r ** np.arange(pade_order + 1)
            num_f = npoly.polymul(num_f, np.array([float(c) for c in p]) * powers)
            den_f = npoly.polymul(den_f, np.array([float(c) for c in q]) * powers)
        return RationalTransfer(num=num_f, den=den_f, time_scale=self.macro_step)
