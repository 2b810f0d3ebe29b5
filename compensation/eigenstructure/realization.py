"""State-space realization of ``T(s) x = 0`` with the rational (Padé) ``D(s)``: the linearisation.

Substituting the Padé form of ``D`` into ``T(s) = Σ D^k s^l P[k, l]`` and clearing denominators
row by row gives a matrix polynomial whose determinant carries spurious factors of the hold
denominator (a row multiplied by ``den(s)^2`` when its determinant only needed ``den(s)``). This
module builds instead a companion-form linearisation that follows the signal flow of the
co-simulation, so that its eigenvalues are exactly the roots of ``det T(s)`` with the rational
``D``, and nothing else:

* a *motion hold* per DOF ``m`` whose displacement crosses the interface
  (``T.exchanged_dofs``, plus any DOF that appears under ``D^2``): ``η' = A η + B x_m``,
  ``x_m* = C η``. Its derivatives ``v_m* = C A η + C B x_m`` and
  ``a_m* = C A^2 η + C A B x_m + C B v_m`` are read out algebraically (one hold per signal, as
  ``D(s v) = s D(s) x``).
* a *force hold* per DOF ``p`` that receives, through the interface, terms computed from signals
  the other side does not exchange (``D P[1, :, p, m]`` with ``m`` not exchanged) or from
  exchanged signals (``D^2 P[2, :, p, m]``): its input is the sum of those terms, as the coupling
  force ``f_c`` (Eq. 12) and the corrected force ``f̃_c = f_c + u_{2,1}`` (Eqs. 37–40) are sent.
* ``D P[1, :, p, m]`` with ``m`` exchanged uses the motion hold of ``m`` directly.

``(A, B, C)`` is the controllable canonical (companion) realization of the rational ``D``
(``RationalTransfer.realization``). The state is ``z = [x, v, η_motion..., η_force...]`` and the
accelerations are eliminated with the effective mass ``P[0, 2]`` (``M`` plus any collocated
acceleration gain), which must be invertible.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.compensation.eigenstructure.dynamic_stiffness import DynamicStiffness
from zencosim.compensation.eigenstructure.interface import RationalTransfer

_EFFECTIVE_MASS_RCOND = 1e-12  # reciprocal condition number below which P[0, 2] is called singular


class SingularMassError(ValueError):
    """The effective mass matrix (``M`` plus collocated acceleration gains) is singular."""


@dataclass(frozen=True)
class StateSpace:
    """``z' = A z`` with ``z = [x, v, η...]``; ``holds`` names each hold in state order."""

    A: np.ndarray
    n_dof: int
    hold_order: int  # states per hold
    holds: tuple[str, ...]  # "motion:<dof>" or "force:<dof>"

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)


def realize(T: DynamicStiffness, D: RationalTransfer) -> StateSpace:
    """Companion-form state-space realization of ``T(s) x = 0`` with ``D(s) = C (sI - A)^{-1} B``."""
    N = T.n_dof
    P = T.P
    Ah, Bh, Ch = D.realization()
    nh = len(Bh)
    nonzero = P != 0.0
    motion = sorted(set(T.exchanged_dofs) | {m for m in range(N) if nonzero[2, :, :, m].any()})
    force = sorted(
        {p for p in range(N) if nonzero[2, :, p, :].any()}
        | {p for p in range(N) for m in range(N) if m not in motion and nonzero[1, :, p, m].any()}
    )
    n_states = 2 * N + nh * (len(motion) + len(force))
    offset = {("motion", m): 2 * N + nh * i for i, m in enumerate(motion)}
    offset.update({("force", p): 2 * N + nh * (len(motion) + i) for i, p in enumerate(force)})

    def dof_signal(m: int, l: int) -> tuple[np.ndarray, np.ndarray]:
        """``s^l x_m`` as (coefficients on z, coefficients on the accelerations)."""
        zrow, arow = np.zeros(n_states), np.zeros(N)
        if l < 2:
            zrow[l * N + m] = 1.0
        else:
            arow[m] = 1.0
        return zrow, arow

    def held_signal(m: int, l: int) -> tuple[np.ndarray, np.ndarray]:
        """``s^l D x_m`` read out of the motion hold of ``m``."""
        o = offset[("motion", m)]
        zrow = np.zeros(n_states)
        zrow[o : o + nh] = Ch @ np.linalg.matrix_power(Ah, l)
        if l >= 1:
            zrow[m] += Ch @ np.linalg.matrix_power(Ah, l - 1) @ Bh
        if l >= 2:
            zrow[N + m] += Ch @ Bh
        return zrow, np.zeros(N)

    def combine(terms) -> tuple[np.ndarray, np.ndarray]:
        zrow, arow = np.zeros(n_states), np.zeros(N)
        for coeff, (zr, ar) in terms:
            zrow += coeff * zr
            arow += coeff * ar
        return zrow, arow

    E = np.zeros((n_states, n_states))  # E z' = F z
    F = np.zeros((n_states, n_states))
    E[:N, :N] = np.eye(N)
    F[:N, N : 2 * N] = np.eye(N)
    for p in range(N):
        terms = [(P[0, l, p, m], dof_signal(m, l)) for m in range(N) for l in range(3) if nonzero[0, l, p, m]]
        terms += [(P[1, l, p, m], held_signal(m, l)) for m in motion for l in range(3) if nonzero[1, l, p, m]]
        zrow, arow = combine(terms)
        if p in force:
            o = offset[("force", p)]
            zrow[o : o + nh] += Ch
        E[N + p, N : 2 * N] = arow
        F[N + p] = -zrow
    for m in motion:
        o = offset[("motion", m)]
        E[o : o + nh, o : o + nh] = np.eye(nh)
        F[o : o + nh, o : o + nh] = Ah
        F[o : o + nh, m] = Bh
    for p in force:
        o = offset[("force", p)]
        terms = [
            (P[1, l, p, m], dof_signal(m, l)) for m in range(N) if m not in motion for l in range(3) if nonzero[1, l, p, m]
        ]
        terms += [(P[2, l, p, m], held_signal(m, l)) for m in motion for l in range(3) if nonzero[2, l, p, m]]
        zrow, arow = combine(terms)
        E[o : o + nh, o : o + nh] = np.eye(nh)
        E[o : o + nh, N : 2 * N] = -np.outer(Bh, arow)
        F[o : o + nh, o : o + nh] += Ah
        F[o : o + nh] += np.outer(Bh, zrow)
    M_eff = P[0, 2]
    if np.linalg.cond(M_eff) * _EFFECTIVE_MASS_RCOND > 1.0:
        raise SingularMassError(
            f"effective mass matrix (M plus collocated acceleration gains) must be invertible; "
            f"its condition number is {np.linalg.cond(M_eff):.3g}"
        )
    A = np.linalg.solve(E, F)
    holds = tuple(f"motion:{m}" for m in motion) + tuple(f"force:{p}" for p in force)
    return StateSpace(A=A, n_dof=N, hold_order=nh, holds=holds)
