"""Eigenstructure of the monolithic and co-simulated systems (paper 000, Eqs. 5 and 7; Tables 1–3, 7–8).

Monolithic: the ``2N`` eigenpairs ``(λ_i, w_i)`` of ``G_t(λ) w = 0``, from the state matrix.

Co-simulated (or compensated): roots of ``det T(s) = 0`` with ``T = G_t + ΔG_c (+ B ΔG_R)``.

1. ``D(s)`` is replaced by its Padé form and the system linearised (``compensation.eigenstructure.realization``);
   the eigenvalues of that state matrix are the roots of the rational model.
2. Each root is polished on the exact ``D(s)`` by Newton's method on ``det T``:
   ``s ← s - 1 / tr(T(s)^{-1} T'(s))``, deflated by the roots already accepted so that it cannot
   fall back onto them. The roots nearest the monolithic poles go first, then the others by
   increasing ``|s|`` (the Padé model is most accurate near the origin); only the closed upper
   half plane is polished, the rest are conjugates. A polished root is accepted when Newton
   converged without leaving a disc of radius ``MAX_POLISH_MOVE |s|`` around the Padé root;
   otherwise the Padé root is kept and flagged.
3. Primary roots: the ``2N`` roots paired one-to-one with the monolithic poles at least total
   distance (an assignment problem); the others are latent roots. Deep latent roots of a low
   Padé order do not correspond to roots of the exact quasi-polynomial (which has infinitely
   many, receding to ``Re s → -∞``); they are reported as the rational model gives them.

Mode shapes are unit Euclidean norm with the largest-modulus entry real and positive. The paper's
tables use the same unit norm but an arbitrary complex phase per table (e.g. Table 1 prints
``-0.9950j`` where Table 3 prints ``-0.9950`` for the same mode), so only the phase-free shape is
comparable. Modal parameters: ``ω_n = |λ|``, ``ξ = -Re λ / |λ|``; errors as in Table 3:
``e_ω = 100 (ω̃_n - ω_n) / ω_n`` [%] and ``e_ξ = ξ̃ - ξ`` (Table 3 lists ``e_ξ = 0.020`` for
``ξ̃ = 0.020, ξ = 0``, which fixes the sign the text leaves ambiguous).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from zencosim.compensation.eigenstructure.dynamic_stiffness import DynamicStiffness
from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.realization import realize
from zencosim.compensation.linear_model import LinearModel

NEWTON_RTOL = 1e-12  # step size, relative to max(|s|, 1), at which Newton has converged
NEWTON_MAX_ITER = 50
MAX_POLISH_MOVE = 0.25  # Newton may move a root by this fraction of max(|s_pade|, 1)


@dataclass(frozen=True)
class Eigenstructure:
    """``2N`` eigenpairs, ordered by natural frequency, positive imaginary part first in each pair."""

    poles: np.ndarray  # (2N,) complex [1/s]
    vectors: np.ndarray  # (N, 2N) complex mode shapes, column i for poles[i]

    @property
    def omega_n(self) -> np.ndarray:
        """Natural frequencies ``|λ|`` [rad/s]."""
        return np.abs(self.poles)

    @property
    def xi(self) -> np.ndarray:
        """Damping ratios ``-Re λ / |λ|``."""
        return -self.poles.real / np.abs(self.poles)


@dataclass(frozen=True)
class CosimEigenstructure:
    """Primary and latent roots of a co-simulated (possibly compensated) system."""

    primary: Eigenstructure  # polished on the exact D(s), paired with the monolithic poles
    primary_pade: np.ndarray  # the same roots of the Padé model, same order [1/s]
    primary_converged: np.ndarray  # (2N,) bool: Newton on the exact D(s) converged
    latent_pade: np.ndarray  # latent roots of the Padé model, by decreasing real part [1/s]
    latent: np.ndarray  # polished where accepted, else the Padé value, same order [1/s]
    latent_converged: np.ndarray  # bool per latent root
    e_omega: np.ndarray  # 100 (ω̃ - ω) / ω [%], per primary pole
    e_xi: np.ndarray  # ξ̃ - ξ, per primary pole

    @property
    def latent_abscissa(self) -> float:
        """Largest real part of the latent roots of the Padé model [1/s] (``-inf`` if none)."""
        return float(np.max(self.latent_pade.real)) if self.latent_pade.size else -np.inf


def normalize_mode_shape(w: np.ndarray) -> np.ndarray:
    """Unit Euclidean norm, largest-modulus entry real and positive."""
    w = np.asarray(w, dtype=complex)
    w = w / np.linalg.norm(w)
    k = np.argmax(np.abs(w))
    return w * np.conj(w[k]) / np.abs(w[k])


def _order_poles(poles: np.ndarray) -> np.ndarray:
    """Indices ordering poles by ``|λ|``, then ``+Im`` before ``-Im``."""
    return np.lexsort((-poles.imag, np.round(np.abs(poles), 9)))


def monolithic_eigenstructure(model: LinearModel) -> Eigenstructure:
    """``(λ_i, w_i)`` of ``G_t(λ) w = 0`` (Eq. 5) from the state matrix ``A`` (Eq. 41)."""
    poles, Z = np.linalg.eig(model.state_matrix())
    order = _order_poles(poles)
    vectors = np.column_stack([normalize_mode_shape(Z[: model.n_dof, i]) for i in order])
    return Eigenstructure(poles=poles[order], vectors=vectors)


def polish_root(
    T: DynamicStiffness, interface: InterfaceModel, s0: complex, known: np.ndarray | None = None
) -> tuple[complex, bool]:
    """Newton on ``det T(s)`` with the exact ``D(s)``, deflated by the roots ``known``.

    Returns ``(s, converged)``. The iterate must stay within ``MAX_POLISH_MOVE * max(|s0|, 1)``
    of ``s0``; leaving that disc counts as not converged (and keeps ``e^{-s T_s}`` bounded).
    ``T(s)`` exactly singular counts as converged.
    """
    known = np.empty(0) if known is None else known
    radius = MAX_POLISH_MOVE * max(abs(s0), 1.0)
    s = complex(s0)
    for _ in range(NEWTON_MAX_ITER):
        D, dD = interface.D(s), interface.dD(s)
        try:
            log_derivative = np.trace(np.linalg.solve(T(s, D), T.derivative(s, D, dD)))
        except np.linalg.LinAlgError:
            return s, True
        step = 1.0 / (log_derivative - np.sum(1.0 / (s - known)))
        s -= step
        if abs(s - s0) > radius:
            return s, False
        if abs(step) <= NEWTON_RTOL * max(abs(s), 1.0):
            return s, True
    return s, False


def mode_shape(T: DynamicStiffness, interface: InterfaceModel, s: complex) -> np.ndarray:
    """Normalised null vector of ``T(s)`` (right singular vector of the smallest singular value)."""
    _, _, Vh = np.linalg.svd(T(s, interface.D(s)))
    return normalize_mode_shape(Vh[-1].conj())


def _conjugate_groups(roots: np.ndarray) -> list[list[int]]:
    """Index groups ``[upper]`` (real root) or ``[upper, lower]`` (conjugate pair).

    The roots are eigenvalues of a real matrix, which LAPACK returns as exactly real values and
    exactly conjugate pairs.
    """
    groups = []
    for i in np.flatnonzero(roots.imag >= 0.0):
        if roots[i].imag == 0.0:
            groups.append([i])
        else:
            groups.append([i, int(np.flatnonzero(roots == np.conj(roots[i]))[0])])
    return groups


def _polish_all(T: DynamicStiffness, interface: InterfaceModel, roots: np.ndarray, first: np.ndarray):
    """Polish ``roots`` pair by pair: groups holding an index of ``first`` first, the rest by ``|s|``.

    Returns polished values and an accepted mask aligned with ``roots`` (a rejected root keeps
    its Padé value).
    """
    polished = roots.astype(complex).copy()
    accepted = np.zeros(len(roots), dtype=bool)
    groups = sorted(_conjugate_groups(roots), key=lambda g: (not np.isin(g, first).any(), abs(roots[g[0]])))
    known: list[complex] = []
    for group in groups:
        s0 = roots[group[0]]
        s, converged = polish_root(T, interface, s0, np.array(known))
        if not converged:
            continue
        if len(group) == 1:
            s = complex(s.real, 0.0)  # a real root of a real system stays real
        values = [s] if len(group) == 1 else [s, np.conj(s)]
        polished[group] = values
        accepted[group] = True
        known.extend(values)
    return polished, accepted


def cosimulated_eigenstructure(
    T: DynamicStiffness, interface: InterfaceModel, pade_order: int, reference: Eigenstructure
) -> CosimEigenstructure:
    """Primary and latent roots of ``T(s) x = 0`` (Eq. 7; Eq. 20 with a compensator in ``T``).

    ``reference`` is the monolithic eigenstructure: it classifies the primary roots and is the
    basis of ``e_ω`` and ``e_ξ``.
    """
    roots = realize(T, interface.rational(pade_order)).eigenvalues()
    _, pade_pick = linear_sum_assignment(np.abs(reference.poles[:, None] - roots[None, :]))
    polished, accepted = _polish_all(T, interface, roots, pade_pick)
    _, pick = linear_sum_assignment(np.abs(reference.poles[:, None] - polished[None, :]))
    latent_idx = np.setdiff1d(np.arange(len(roots)), pick)
    latent_idx = latent_idx[np.argsort(-roots[latent_idx].real, kind="stable")]
    poles = polished[pick]
    vectors = np.column_stack([mode_shape(T, interface, s) for s in poles])
    primary = Eigenstructure(poles=poles, vectors=vectors)
    return CosimEigenstructure(
        primary=primary,
        primary_pade=roots[pick],
        primary_converged=accepted[pick],
        latent_pade=roots[latent_idx],
        latent=polished[latent_idx],
        latent_converged=accepted[latent_idx],
        e_omega=100.0 * (primary.omega_n - reference.omega_n) / reference.omega_n,
        e_xi=primary.xi - reference.xi,
    )
