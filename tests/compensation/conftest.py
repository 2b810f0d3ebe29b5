"""The paper's benchmark models (paper 000, §2.3.2 and §6.2), built directly as ``LinearModel``."""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.compensation.linear_model import ForceDisplacementBond, LinearModel


def _chain(ground_left: float, links: list[float], ground_right: float) -> np.ndarray:
    """Tridiagonal matrix of a chain of springs (or dampers): ground, links between bodies, ground."""
    values = [ground_left, *links, ground_right]
    n = len(values) - 1
    A = np.zeros((n, n))
    for i in range(n):
        A[i, i] = values[i] + values[i + 1]
    for i in range(n - 1):
        A[i, i + 1] = A[i + 1, i] = -values[i + 1]
    return A


def build_two_mass(damping: float, macro_step: float) -> LinearModel:
    """§2.3.2: m1 = m2 = 1 kg, k1 = 10, k2 = 1000, kc = 100 N/m, c1 = c2 = cc = ``damping`` N s/m.

    Mass 1 (subsystem 1) computes the coupling force, mass 2 (subsystem 2) sends x2 (Fig. 2).
    """
    m1 = m2 = 1.0
    k1, k2, kc = 10.0, 1000.0, 100.0
    c1 = c2 = cc = damping
    return LinearModel(
        M=np.diag([m1, m2]),
        C=_chain(c1, [cc], c2),
        K=_chain(k1, [kc], k2),
        dof_names=("s1.m1", "s2.m2"),
        dof_subsystem=("s1", "s2"),
        bonds=(ForceDisplacementBond("coupling", force_dof=0, motion_dof=1, stiffness=kc, damping=cc),),
        macro_step=macro_step,
    )


def build_four_mass(macro_step: float = 3e-3) -> LinearModel:
    """§6.2: m_i = i kg, k_i = 100 i N/m, c_i = 0.01 i N s/m (i = 1..5 for springs and dampers).

    Subsystem 1 holds masses 1–2, subsystem 2 masses 3–4; the bond is spring/damper 3 between
    masses 2 and 3, mass 2 computes f_c and mass 3 sends x3 (Eq. 46).
    """
    k = [100.0 * i for i in range(1, 6)]
    c = [0.01 * i for i in range(1, 6)]
    return LinearModel(
        M=np.diag([1.0, 2.0, 3.0, 4.0]),
        C=_chain(c[0], c[1:4], c[4]),
        K=_chain(k[0], k[1:4], k[4]),
        dof_names=("s1.m1", "s1.m2", "s2.m3", "s2.m4"),
        dof_subsystem=("s1", "s1", "s2", "s2"),
        bonds=(ForceDisplacementBond("coupling", force_dof=1, motion_dof=2, stiffness=k[2], damping=c[2]),),
        macro_step=macro_step,
    )


@pytest.fixture
def two_mass():
    return build_two_mass


@pytest.fixture
def four_mass():
    return build_four_mass
