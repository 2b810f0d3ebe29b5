"""Linear second-order model of a scene: the monolithic system and its force–displacement bonds.

Paper 000, Eqs. (3), (9)–(11): ``M x'' + C x' + K x = f_e``. The matrices are assembled from the
subsystems and the couplings of a linear scene (the assembly from a scene lives with the scene
builder in ``manager``; this module only holds the result, so that ``compensation`` never needs
to know about scenes, Zenoh or MCAP).

Sign convention of a force–displacement bond (paper 000 Fig. 2, paper 002 Fig. 8): the coupling
element (spring ``stiffness``, damper ``damping``) lives in the force-side subsystem, acts on DOF
``force_dof`` and reads the exchanged displacement and velocity of DOF ``motion_dof``; the force it
exerts on ``force_dof`` is ``fc = -k (x_f - x_m*) - c (v_f - v_m*)`` (the paper's sign) and the
motion side feels ``-fc*``. The runtime's force signal is that ``-fc``, the force on the motion DOF,
which the motion side applies as it receives it (``subsystems.ports``); the maths here is the paper's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ForceDisplacementBond:
    """One force–displacement coupling between two bodies of two subsystems."""

    name: str
    force_dof: int  # index of the force-side body in the monolithic numbering
    motion_dof: int  # index of the motion-side body in the monolithic numbering
    stiffness: float  # coupling stiffness k_c [N/m]
    damping: float  # coupling damping c_c [N s/m]


@dataclass(frozen=True)
class LinearModel:
    """Monolithic ``M, C, K`` of a linear scene and the bonds that cross the co-simulation interface."""

    M: np.ndarray  # mass matrix [kg], N x N
    C: np.ndarray  # damping matrix [N s/m], N x N
    K: np.ndarray  # stiffness matrix [N/m], N x N
    dof_names: tuple[str, ...]  # "<subsystem>.<body>" for each DOF
    dof_subsystem: tuple[str, ...]  # owning subsystem of each DOF
    bonds: tuple[ForceDisplacementBond, ...]
    macro_step: float  # T_s [s]

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]

    def state_matrix(self) -> np.ndarray:
        """First-order state matrix ``A`` of ``z = [x, v]`` (paper 000 Eq. 41)."""
        n = self.n_dof
        Minv = np.linalg.inv(self.M)
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -Minv @ self.K
        A[n:, n:] = -Minv @ self.C
        return A
