"""Dynamic stiffness of a co-simulated linear system as a polynomial in ``s`` and ``D(s)``.

Paper 000 writes the co-simulated (Eq. 6) and compensated (Eq. 19) systems as
``(G_t(s) + ΔG_c(s) + B ΔG_R(s)) x(s) = f_e(s)``. Every term is a quadratic polynomial in ``s``
times a power of the interface transfer function: a signal crosses the interface at most twice
(a displacement sent to the force side, then a force computed from it sent back, Eq. 13), so

    T(s) = Σ_{k=0}^{2} Σ_{l=0}^{2} D(s)^k s^l P[k, l],   P[k, l] ∈ R^{N x N}.

``exchanged_dofs`` lists the DOFs whose displacement is itself a signal of the interface (the
motion side of a force–displacement bond); the state-space realization uses it to share one hold
between every use of that signal (``compensation.eigenstructure.realization``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_HOLD_POWER = 2  # k in D(s)^k
MAX_S_POWER = 2  # l in s^l


@dataclass(frozen=True)
class DynamicStiffness:
    """``T(s) = Σ_k Σ_l D(s)^k s^l P[k, l]``."""

    P: np.ndarray  # shape (3, 3, N, N); P[k, l] multiplies D^k s^l [N/m · s^l]
    exchanged_dofs: tuple[int, ...] = ()

    def __post_init__(self):
        shape = np.shape(self.P)
        if len(shape) != 4 or shape[:2] != (MAX_HOLD_POWER + 1, MAX_S_POWER + 1) or shape[2] != shape[3]:
            raise ValueError(
                f"P must have shape (3, 3, N, N) (powers of D, powers of s, rows, columns); got {shape}"
            )

    @classmethod
    def zeros(cls, n_dof: int, exchanged_dofs: tuple[int, ...] = ()) -> DynamicStiffness:
        return cls(np.zeros((MAX_HOLD_POWER + 1, MAX_S_POWER + 1, n_dof, n_dof)), exchanged_dofs)

    @property
    def n_dof(self) -> int:
        return self.P.shape[2]

    def __add__(self, other: DynamicStiffness) -> DynamicStiffness:
        exchanged = tuple(sorted(set(self.exchanged_dofs) | set(other.exchanged_dofs)))
        return DynamicStiffness(self.P + other.P, exchanged)

    def __call__(self, s: complex, D: complex) -> np.ndarray:
        """``T(s)`` for a given value ``D = D(s)``."""
        Dk = D ** np.arange(MAX_HOLD_POWER + 1)
        sl = s ** np.arange(MAX_S_POWER + 1)
        return np.einsum("k,l,klij->ij", Dk, sl, self.P)

    def derivative(self, s: complex, D: complex, dD: complex) -> np.ndarray:
        """``dT/ds`` for given ``D = D(s)`` and ``dD = dD/ds``."""
        k = np.arange(MAX_HOLD_POWER + 1)
        l = np.arange(MAX_S_POWER + 1)
        Dk = D ** k
        dDk = np.where(k > 0, k * D ** np.maximum(k - 1, 0), 0.0) * dD
        sl = s ** l
        dsl = np.where(l > 0, l * s ** np.maximum(l - 1, 0), 0.0)
        return np.einsum("k,l,klij->ij", dDk, sl, self.P) + np.einsum("k,l,klij->ij", Dk, dsl, self.P)
