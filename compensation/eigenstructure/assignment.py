"""Eigenstructure assignment for co-simulation compensation (paper 000, §3.2–3.3, §4, §6.1).

The compensated system must keep every monolithic eigenpair ``(λ_i, w_i)``: since
``G_t(λ_i) w_i = 0``, Eq. 20 reduces to (Eq. 21)

    (ΔG_c(λ_i) + B ΔG_R(λ_i)) w_i = 0,   i = 1..2N,

linear in the gains ``k = [d; f; g]``: ``L k = n`` (Eq. 22) with, for every eigenpair and every
row ``p`` that the interface perturbs or a force acts on, ``L[(i, p), c] = (∂(BΔG_R)/∂k_c (λ_i)
w_i)_p`` and ``n[(i, p)] = -(ΔG_c(λ_i) w_i)_p`` (Eqs. 27–28, 48). ``D`` is evaluated exactly at
``λ_i``.

Gains must be real, so the system solved is the stacked ``[Re L; Im L] k = [Re n; Im n]``
(Eq. 29). Its rank equals the complex rank of ``L`` because the eigenpairs are closed under
conjugation, so the ranks reported are those of §4.3. Before any rank decision or solve the
columns are scaled to unit norm (``λ^2``-columns are ``|λ|^2`` times larger than ``g``-columns;
the rank is unchanged by the scaling): a singular value counts when it exceeds
``RANK_RTOL`` times the largest. ``RANK_RTOL = 1e-8`` sits above round-off (the structural
zero singular values of the paper's cases are ``< 1e-15``) and below the smallest genuine ones
(``>= 0.25`` for the two-mass cases, ``3e-8`` for the four-mass one, discussed below); all are
reported in ``Assignability`` so the gap can be checked.

Solution (Eq. 23): ``k = k_0 + V k_r`` from the SVD of the column-scaled stacked ``L``:
``k_0`` is the minimum-norm solution on the leading ``rank_used`` singular directions and ``V``
an orthonormal basis of the rest, both in the column-scaled variables. ``rank_used`` starts at
``rank L`` and drops one direction at a time while the compensated effective mass
``M_eff = M + (collocated acceleration gains)`` keeps less than ``MIN_MASS_RATIO`` of ``M`` in
some direction (smallest singular value of ``C^{-1} M_eff C^{-T}``, ``M = C C^T``). A singular
``M_eff`` is what an identically singular ``det T(s)`` looks like (its leading coefficient is
``det M_eff``), and it happens: for the four-mass architecture of Eq. 47, row 2 of Eq. 48 must
satisfy ``r_1 w_1 + r_2 w_2 + r_3 D w_3 = -n_2`` at eight eigenpairs with nine gains, solved
for every ``s`` by ``-(g_21, g_22, g_23)`` (row 2 of ``G_t`` with ``D`` on ``x_3``) plus the
one-dimensional null space, row 1 of ``G_t``, which has no ``s^2 x_2`` term; so every exact
solution has ``d_2 = -m_2`` and makes row 2 of the compensated ``T`` a multiple of row 1. The
direction that carries it has a small singular value (``3e-8`` at 3 ms with ZOH, ``4e-6`` with
FOH) and dropping it leaves a ``residual`` ``||L k - n|| / ||n||`` that is reported; the
assigned poles are then approximate (``4e-7`` rad/s off at 3 ms with ZOH).

``k_r`` leaves the assigned eigenpairs untouched and is chosen for the latent roots of the
(Padé) compensated system: ``k_r = 0`` if it already gives ``Re s <= -margin``; otherwise the
largest real part of the latent roots is minimised by Nelder–Mead, first from ``k_r = 0`` then
from seeded random starts, stopping at the first ``k_r`` that meets the margin (the paper used a
random search; its gains are not reproduced).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment, minimize

from zencosim.compensation.eigenstructure.architecture import Architecture
from zencosim.compensation.eigenstructure.dynamic_stiffness import DynamicStiffness
from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.modes import Eigenstructure, monolithic_eigenstructure
from zencosim.compensation.eigenstructure.perturbation import (
    cosimulated_stiffness,
    interface_perturbation,
    monolithic_stiffness,
)
from zencosim.compensation.eigenstructure.realization import SingularMassError, realize
from zencosim.compensation.linear_model import LinearModel

RANK_RTOL = 1e-8
MIN_MASS_RATIO = 0.5  # compensation may remove at most half of the inertia in any direction


class NotAssignableError(ValueError):
    """The architecture cannot assign the monolithic eigenstructure (Eq. 33 fails, or only with ``M_eff`` singular)."""

    def __init__(self, architecture: str, assignability: Assignability, reason: str | None = None):
        self.assignability = assignability
        reason = reason or (
            f"expected rank L = rank [L n] (Eq. 33); got rank L = {assignability.rank_L}, "
            f"rank [L n] = {assignability.rank_Ln}"
        )
        super().__init__(f"architecture {architecture!r} cannot assign the monolithic eigenstructure: {reason}")


@dataclass(frozen=True)
class AssignmentSystem:
    """``L k = n`` of Eq. 22, rows ordered eigenpair-major, then ``rows``; columns are the free gains."""

    L: np.ndarray  # (2N * p, len(columns)) complex
    n: np.ndarray  # (2N * p,) complex
    rows: tuple[int, ...]  # the p DOF rows kept (perturbed by ΔG_c or acted on by B)
    columns: tuple[int, ...]  # index into k = [d; f; g] of each column (Architecture.free_gains)

    def stacked(self) -> tuple[np.ndarray, np.ndarray]:
        """Real form ``[Re L; Im L], [Re n; Im n]`` (Eq. 29)."""
        return np.vstack([self.L.real, self.L.imag]), np.concatenate([self.n.real, self.n.imag])


@dataclass(frozen=True)
class Assignability:
    """Rouché–Capelli test of Eq. 33 on the stacked real system, column-scaled."""

    rank_L: int
    rank_Ln: int
    singular_values_L: np.ndarray  # of the column-scaled stacked L, descending
    singular_values_Ln: np.ndarray  # of the column-scaled stacked [L n], descending
    rtol: float

    @property
    def assignable(self) -> bool:
        return self.rank_L == self.rank_Ln


@dataclass(frozen=True)
class CompensatorDesign:
    """Gains of an assignable architecture and the latent-root margin they reach."""

    architecture: Architecture
    system: AssignmentSystem
    assignability: Assignability
    rank_used: int  # leading singular directions of L used to fit n
    residual: float  # ||L k - n|| / ||n|| of the stacked system
    k0: np.ndarray  # particular solution [d; f; g]
    V: np.ndarray  # (3 n_terms, len(free gains) - rank_used) null-space basis of L in gain units, zero rows for fixed gains
    k_r: np.ndarray  # null-space coordinates chosen for the latent roots
    k: np.ndarray  # k0 + V k_r
    latent_abscissa: float  # max Re of the latent roots of the compensated Padé model [1/s]
    margin: float  # requested: latent_abscissa <= -margin [1/s]
    pade_order: int
    seed: int

    @property
    def margin_met(self) -> bool:
        return self.latent_abscissa <= -self.margin

    @property
    def d(self) -> np.ndarray:
        return self.k[: self.architecture.n_terms]

    @property
    def f(self) -> np.ndarray:
        return self.k[self.architecture.n_terms : 2 * self.architecture.n_terms]

    @property
    def g(self) -> np.ndarray:
        return self.k[2 * self.architecture.n_terms :]

    def stiffness(self, n_dof: int) -> DynamicStiffness:
        """``B ΔG_R(s)`` with the designed gains."""
        return self.architecture.stiffness(self.k, n_dof)


def assignment_system(
    model: LinearModel,
    interface: InterfaceModel,
    architecture: Architecture,
    monolithic: Eigenstructure,
    poles: np.ndarray | None = None,
) -> AssignmentSystem:
    """``L`` and ``n`` of Eqs. 27–28 (two-mass) and 48 (four-mass), built for any architecture.

    Only the free gains are columns: a gain fixed at zero does not enter ``L``. ``poles`` (same
    order as ``monolithic.poles``) assigns other poles than the monolithic ones: Eq. 20 is then
    used as it stands, ``n = -(G_t + ΔG_c)(λ̃_i) w̃_i``, with ``w̃_i`` the monolithic mode shape
    changed least (minimum norm) so that the rows no force acts on hold, ``(G_t(λ̃_i) w̃_i)_p = 0``.
    """
    N = model.n_dof
    columns = architecture.free_gains
    directions = architecture.gain_directions(N)[list(columns)]
    dG = interface_perturbation(model)
    touched = np.any(dG.P != 0.0, axis=(0, 1, 3)) | np.any(directions != 0.0, axis=(0, 1, 2, 4))
    rows = np.flatnonzero(touched)
    G_t = monolithic_stiffness(model)
    L_blocks, n_blocks = [], []
    targets = monolithic.poles if poles is None else np.asarray(poles)
    for lam, D, w in zip(targets, interface.D(targets), monolithic.vectors.T):
        if poles is not None:
            untouched = G_t(lam, 1.0)[~touched]
            w = w - np.linalg.pinv(untouched) @ (untouched @ w) if untouched.size else w
        powers_D, powers_s = D ** np.arange(directions.shape[1]), lam ** np.arange(directions.shape[2])
        L_blocks.append(np.einsum("k,l,cklij,j->ic", powers_D, powers_s, directions, w)[rows])
        n_blocks.append(-((dG(lam, D) + (0.0 if poles is None else G_t(lam, D))) @ w)[rows])
    return AssignmentSystem(L=np.vstack(L_blocks), n=np.concatenate(n_blocks), rows=tuple(int(r) for r in rows),
                            columns=columns)


def _column_scales(A: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(A, axis=0)
    return np.where(norms > 0.0, norms, 1.0)


def assess_assignability(system: AssignmentSystem, rtol: float = RANK_RTOL) -> Assignability:
    """``rank L`` and ``rank [L n]`` (Eq. 33) with the column scaling and tolerance stated above."""
    L, n = system.stacked()
    Ln = np.column_stack([L, n])
    sv_L = np.linalg.svd(L / _column_scales(L), compute_uv=False)
    sv_Ln = np.linalg.svd(Ln / _column_scales(Ln), compute_uv=False)
    return Assignability(
        rank_L=int(np.sum(sv_L > rtol * sv_L[0])),
        rank_Ln=int(np.sum(sv_Ln > rtol * sv_Ln[0])),
        singular_values_L=sv_L,
        singular_values_Ln=sv_Ln,
        rtol=rtol,
    )


def mass_ratio(M: np.ndarray, M_eff: np.ndarray) -> float:
    """Smallest singular value of ``C^{-1} M_eff C^{-T}`` with ``M = C C^T``: 1 for ``M_eff = M``."""
    C = np.linalg.cholesky(M)
    X = np.linalg.solve(C, np.linalg.solve(C, M_eff).T).T
    return float(np.linalg.svd(X, compute_uv=False)[-1])


def latent_abscissa(
    T: DynamicStiffness, interface: InterfaceModel, pade_order: int, monolithic: Eigenstructure
) -> float:
    """Largest real part of the latent roots of ``T`` with the Padé ``D``: all roots but the ``2N``
    paired with the monolithic poles [1/s]. ``+inf`` when the effective mass is singular."""
    try:
        roots = realize(T, interface.rational(pade_order)).eigenvalues()
    except SingularMassError:
        return np.inf
    _, pick = linear_sum_assignment(np.abs(monolithic.poles[:, None] - roots[None, :]))
    latent = np.delete(roots, pick)
    return float(np.max(latent.real)) if latent.size else -np.inf


def design_compensator(
    model: LinearModel,
    interface: InterfaceModel,
    architecture: Architecture,
    pade_order: int = 6,
    margin: float | None = None,
    seed: int = 0,
    restarts: int = 8,
    poles: np.ndarray | None = None,
) -> CompensatorDesign:
    """Gains ``k`` that assign the monolithic eigenstructure and keep the latent roots at ``Re s <= -margin``.

    ``poles`` replaces the monolithic poles as targets (``assignment_system``); the latent roots
    are still the roots not paired with the monolithic poles.

    ``margin`` [1/s] defaults to ``0.1 / T_s``. Raises ``NotAssignableError`` (carrying the
    ``Assignability`` report) when Eq. 33 fails or when no truncation keeps ``M_eff`` regular.
    If no start reaches the margin, the best ``k_r`` found is returned and ``margin_met`` is
    False: the caller decides.
    """
    margin = 0.1 / interface.macro_step if margin is None else margin
    monolithic = monolithic_eigenstructure(model)
    system = assignment_system(model, interface, architecture, monolithic, poles)
    assignability = assess_assignability(system)
    if not assignability.assignable:
        raise NotAssignableError(architecture.name, assignability)
    base = cosimulated_stiffness(model)

    def well_posed(k: np.ndarray) -> bool:
        M_eff = base.P[0, 2] + architecture.stiffness(k, model.n_dof).P[0, 2]
        return mass_ratio(model.M, M_eff) >= MIN_MASS_RATIO

    L, n = system.stacked()
    scales = _column_scales(L)
    U, S, Vt = np.linalg.svd(L / scales)
    free = list(system.columns)
    for rank_used in range(assignability.rank_L, 0, -1):
        k0_scaled = Vt[:rank_used].T @ ((U[:, :rank_used].T @ n) / S[:rank_used])
        k0, V = np.zeros(architecture.n_gains), np.zeros((architecture.n_gains, len(free) - rank_used))
        k0[free], V[free] = k0_scaled / scales, Vt[rank_used:].T / scales[:, None]
        if well_posed(k0):
            break
    else:
        raise NotAssignableError(architecture.name, assignability, "every solution removes the inertia of the system")
    residual = float(np.linalg.norm(L @ k0[free] - n) / np.linalg.norm(n))

    def abscissa(k_r: np.ndarray) -> float:
        k = k0 + V @ k_r
        if not well_posed(k):
            return np.inf
        return latent_abscissa(base + architecture.stiffness(k, model.n_dof), interface, pade_order, monolithic)

    def objective(k_r: np.ndarray) -> float:  # flat once the margin is met
        return max(abscissa(k_r), -margin)

    def stop_at_margin(intermediate_result) -> None:
        if intermediate_result.fun <= -margin:
            raise StopIteration

    rng = np.random.default_rng(seed)
    spread = max(np.linalg.norm(k0_scaled), 1.0)
    best_k_r = np.zeros(V.shape[1])
    start_abscissa = abscissa(best_k_r)
    best = max(start_abscissa, -margin)  # objective(best_k_r)
    for attempt in range(restarts + 1):
        if best <= -margin or V.shape[1] == 0:
            break
        start = np.zeros(V.shape[1]) if attempt == 0 else spread * rng.standard_normal(V.shape[1])
        result = minimize(
            objective, start, method="Nelder-Mead", callback=stop_at_margin, options={"maxfev": 400 * V.shape[1]}
        )
        if result.fun < best:
            best_k_r, best = result.x, float(result.fun)
    return CompensatorDesign(
        architecture=architecture,
        system=system,
        assignability=assignability,
        rank_used=rank_used,
        residual=residual,
        k0=k0,
        V=V,
        k_r=best_k_r,
        k=k0 + V @ best_k_r,
        latent_abscissa=start_abscissa if not best_k_r.any() else abscissa(best_k_r),
        margin=margin,
        pade_order=pade_order,
        seed=seed,
    )
