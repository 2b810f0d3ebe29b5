"""Compensator architectures as data: where the forces act and which signals they feed back.

Paper 000, Eq. 18: ``u(s) = -ΔG_R(s) x(s)`` distributed by ``B``, so the compensated system is
``(G_t + ΔG_c + B ΔG_R) x = f_e`` (Eq. 19). Each compensation force ``u`` is a sum of feedback
terms ``r(s) y`` with ``r(s) = s^2 d + s f + g`` (acceleration, velocity and displacement gains)
and ``y`` either a DOF of the force's own subsystem (collocated, ``x_m``) or a signal received
through the interface (``x_m* = D(s) x_m``). A force acts on one or more DOFs, directly or — when
it is computed in the other subsystem and sent over — through ``D(s)`` (the rank-one
``B = {1, -D(s)}^T`` of Eq. 34).

The gain vector is ``k = [d; f; g]`` (Eq. 22), each block listing the feedback terms force by
force in declaration order: for the two-mass system of Eq. 24 ``d = [d_1, d_2, d_3, d_4]`` with
``d_1: x_1``, ``d_2: x_2*``, ``d_3: x_1*``, ``d_4: x_2``. A term declared without acceleration
feedback keeps its place in ``d`` with the gain fixed at zero (``Architecture.free_gains`` lists
the gains a design may choose).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.compensation.eigenstructure.dynamic_stiffness import DynamicStiffness
from zencosim.compensation.linear_model import ForceDisplacementBond, LinearModel

GAIN_KINDS = ("d", "f", "g")  # blocks of k; s-power 2, 1, 0 (acceleration, velocity, displacement)
_S_POWER = {"d": 2, "f": 1, "g": 0}


class ArchitectureError(ValueError):
    """An architecture does not fit the model it is applied to."""


@dataclass(frozen=True)
class FeedbackTerm:
    """``r(s) x_dof`` (collocated) or ``r(s) D(s) x_dof`` (``through_hold``: the exchanged ``x_dof*``).

    ``acceleration=False`` fixes ``d = 0`` in ``r(s) = s^2 d + s f + g``.
    """

    dof: int
    through_hold: bool = False
    acceleration: bool = True


@dataclass(frozen=True)
class Actuation:
    """The force enters DOF ``dof`` as ``sign * u``, or as ``sign * D(s) u`` when ``through_hold``."""

    dof: int
    sign: float = 1.0
    through_hold: bool = False


@dataclass(frozen=True)
class CompensationForce:
    """One independent compensation force: one column of ``B`` and one row of ``ΔG_R``."""

    name: str
    actuations: tuple[Actuation, ...]
    feedback: tuple[FeedbackTerm, ...]


@dataclass(frozen=True)
class Architecture:
    """A set of compensation forces; ``k = [d; f; g]`` has three gains per feedback term."""

    name: str
    forces: tuple[CompensationForce, ...]

    @property
    def n_terms(self) -> int:
        """Number of feedback terms (``r`` in the paper's ``3 m r`` when every force uses ``r`` signals)."""
        return sum(len(u.feedback) for u in self.forces)

    @property
    def n_gains(self) -> int:
        return 3 * self.n_terms

    @property
    def free_gains(self) -> tuple[int, ...]:
        """Indices into ``k`` of the gains a design chooses; the others are fixed at zero."""
        terms = [term for u in self.forces for term in u.feedback]
        d = [t for t, term in enumerate(terms) if term.acceleration]
        return tuple(d) + tuple(range(self.n_terms, self.n_gains))

    def gain_labels(self) -> tuple[str, ...]:
        """``"d1"``, ..., ``"g<n_terms>"`` in the order of ``k``, numbered as in Eqs. 24 and 47."""
        return tuple(f"{kind}{t + 1}" for kind in GAIN_KINDS for t in range(self.n_terms))

    def check(self, n_dof: int) -> None:
        """Raise ``ArchitectureError`` if a DOF is out of range or a force has no actuation or feedback."""
        for u in self.forces:
            if not u.actuations or not u.feedback:
                raise ArchitectureError(f"force {u.name!r} of {self.name!r} needs at least one actuation and one feedback term")
            for item in u.actuations + u.feedback:
                if not 0 <= item.dof < n_dof:
                    raise ArchitectureError(
                        f"force {u.name!r} of {self.name!r} names DOF {item.dof}; expected 0..{n_dof - 1}"
                    )

    def gain_directions(self, n_dof: int) -> np.ndarray:
        """``∂(B ΔG_R)/∂k_c`` for every gain, shape ``(n_gains, 3, 3, N, N)`` in ``DynamicStiffness.P`` layout.

        ``B ΔG_R`` is linear in ``k``: a term ``(m, f)`` of a force acting on ``(p, σ, a)`` adds
        ``σ D^{a+f} s^l`` at ``[p, m]`` per unit gain, ``l = 2, 1, 0`` for ``d, f, g``.
        """
        self.check(n_dof)
        G = np.zeros((self.n_gains, 3, 3, n_dof, n_dof))
        t = 0
        for u in self.forces:
            for term in u.feedback:
                for block, kind in enumerate(GAIN_KINDS):
                    for act in u.actuations:
                        hold_power = int(act.through_hold) + int(term.through_hold)
                        G[block * self.n_terms + t, hold_power, _S_POWER[kind], act.dof, term.dof] += act.sign
                t += 1
        return G

    def stiffness(self, k: np.ndarray, n_dof: int) -> DynamicStiffness:
        """``B ΔG_R(s)`` for the gains ``k = [d; f; g]``."""
        k = np.asarray(k, dtype=float)
        if k.shape != (self.n_gains,):
            raise ArchitectureError(f"{self.name!r} expects {self.n_gains} gains [d; f; g]; got shape {k.shape}")
        return DynamicStiffness(np.einsum("c,cklij->klij", k, self.gain_directions(n_dof)))


def _single_bond(model: LinearModel, architecture: str) -> ForceDisplacementBond:
    if len(model.bonds) != 1:
        raise ArchitectureError(f"{architecture} is defined for one force–displacement bond; the model has {len(model.bonds)}")
    return model.bonds[0]


def _subsystem_dofs(model: LinearModel, dof: int) -> tuple[int, ...]:
    return tuple(m for m in range(model.n_dof) if model.dof_subsystem[m] == model.dof_subsystem[dof])


def full_feedback(model: LinearModel, exchanged_motion: bool = True, exchanged_acceleration: bool = True) -> Architecture:
    """Two forces, on the force DOF ``i`` and the motion DOF ``j`` of the model's single bond (``B`` of rank 2).

    ``u_1`` on ``i`` feeds back every DOF of ``i``'s subsystem (collocated) and ``x_j*``;
    ``u_2`` on ``j`` feeds back every DOF of ``i``'s subsystem through ``D(s)`` (computed there
    and sent with ``f_c``, Eqs. 37–40) and every DOF of ``j``'s subsystem (collocated).
    Two-mass system: Eq. 24 (``B = I_2``). Four-mass system: Eqs. 47–48 (``u_1`` does not see
    ``x_4``). ``exchanged_motion=False`` drops ``x_j*`` from ``u_1`` (the output-feedback case of
    §4.3, "omit x_2*"); ``exchanged_acceleration=False`` keeps ``x_j*`` and ``v_j*`` but fixes the
    gain of its acceleration at zero (the runtime's architecture, docs/compensation.md).
    """
    name = "full_feedback" if exchanged_motion else "full_feedback_without_exchanged_motion"
    if exchanged_motion and not exchanged_acceleration:
        name = "full_feedback_without_exchanged_acceleration"
    bond = _single_bond(model, name)
    i, j = bond.force_dof, bond.motion_dof
    force_side, motion_side = _subsystem_dofs(model, i), _subsystem_dofs(model, j)
    exchanged = (FeedbackTerm(j, True, exchanged_acceleration),) if exchanged_motion else ()
    u_1 = tuple(FeedbackTerm(m) for m in force_side) + exchanged
    u_2 = tuple(FeedbackTerm(m, True) for m in force_side) + tuple(FeedbackTerm(m) for m in motion_side)
    return Architecture(
        name=name,
        forces=(
            CompensationForce("u_1", (Actuation(i),), u_1),
            CompensationForce("u_2", (Actuation(j),), u_2),
        ),
    )


def rank_one(model: LinearModel) -> Architecture:
    """One force ``u`` computed on the force side, ``B = {1, -D(s)}^T`` (Eqs. 34–35).

    ``u`` feeds back every DOF of the force DOF's subsystem (collocated) and ``x_j*``; it acts on
    the force DOF ``i`` and, sent through the interface with opposite sign, on the motion DOF ``j``.
    """
    bond = _single_bond(model, "rank_one")
    i, j = bond.force_dof, bond.motion_dof
    feedback = tuple(FeedbackTerm(m) for m in _subsystem_dofs(model, i)) + (FeedbackTerm(j, True),)
    u = CompensationForce("u", (Actuation(i), Actuation(j, sign=-1.0, through_hold=True)), feedback)
    return Architecture(name="rank_one", forces=(u,))
