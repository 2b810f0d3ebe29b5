"""Monolithic dynamic stiffness ``G_t(s)`` and interface perturbation ``ΔG_c(s)`` (paper 000, §2).

``G_t(s) = s^2 M + s C + K`` (Eq. 4). For a force–displacement bond with coupling element
``g_c(s) = s c_c + k_c`` between force DOF ``i`` and motion DOF ``j`` (``compensation.linear_model``):
the force side computes ``f_c = -g_c (x_i - D x_j)`` from the received ``x_j* = D x_j`` and the
motion side applies ``-f_c* = -D f_c`` (Eq. 12). Subtracting the monolithic rows
``(G_i + g_c) x_i - g_c x_j`` and ``(G_j + g_c) x_j - g_c x_i`` from these gives

    ΔG[i, j] += g_c (1 - D),   ΔG[j, i] += g_c (1 - D),   ΔG[j, j] += g_c (D^2 - 1),

which for the two-mass system is Eq. 15 (``i = 1, j = 2``) and for the four-mass system Eq. 46
(``i = 2, j = 3``). Bonds add up; ``D = 1`` gives ``ΔG_c = 0``.
"""
from __future__ import annotations

import numpy as np

from zencosim.compensation.eigenstructure.dynamic_stiffness import DynamicStiffness
from zencosim.compensation.linear_model import LinearModel


class BondSpecError(ValueError):
    """A bond names a DOF outside the model or the same DOF on both sides."""


def monolithic_stiffness(model: LinearModel) -> DynamicStiffness:
    """``G_t(s) = s^2 M + s C + K`` (Eq. 4)."""
    T = DynamicStiffness.zeros(model.n_dof)
    T.P[0, 0], T.P[0, 1], T.P[0, 2] = model.K, model.C, model.M
    return T


def interface_perturbation(model: LinearModel) -> DynamicStiffness:
    """``ΔG_c(s)`` assembled from the model's force–displacement bonds (Eqs. 12–15, 46)."""
    N = model.n_dof
    dG = DynamicStiffness.zeros(N, tuple(sorted({b.motion_dof for b in model.bonds})))
    for bond in model.bonds:
        i, j = bond.force_dof, bond.motion_dof
        if not (0 <= i < N and 0 <= j < N) or i == j:
            raise BondSpecError(
                f"bond {bond.name!r}: expected two distinct DOFs in 0..{N - 1}; got force_dof={i}, motion_dof={j}"
            )
        g_c = np.array([bond.stiffness, bond.damping, 0.0])  # coefficients of s^0, s^1, s^2
        for row, col in ((i, j), (j, i)):  # g_c (1 - D)
            dG.P[0, :, row, col] += g_c
            dG.P[1, :, row, col] -= g_c
        dG.P[2, :, j, j] += g_c  # g_c (D^2 - 1)
        dG.P[0, :, j, j] -= g_c
    return dG


def cosimulated_stiffness(model: LinearModel) -> DynamicStiffness:
    """``G_t(s) + ΔG_c(s)`` (Eq. 6)."""
    return monolithic_stiffness(model) + interface_perturbation(model)
