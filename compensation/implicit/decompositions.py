"""The three decompositions of the two-mass test model (paper 003, §2.1 force/force, §2.2
force/displacement, §2.3 displacement/displacement) and their linearised coupling conditions.

Each mass is one subsystem with state ``z = (x, v)``, one input ``u`` (a coupling variable) and four
interface outputs ``y = (x, v, a, f)``: position, velocity, acceleration and the coupling force ``f``
acting on it, with ``m a = -c x - d v + s f`` and ``s = +1`` for mass 1, ``-1`` for mass 2 (Eq. 4).

* force-driven (Eqs. 7a, 7b, 33a): ``u = f = lambda_c``; the acceleration follows from the force.
* displacement-driven (Eqs. 33b, 57a, 57b), on acceleration (index-1) level: ``u = a`` is prescribed
  and ``f`` is the multiplier ``mu_i`` of the rheonomic constraint ``v' - a = 0``,
  ``f = s (m a + c x + d v)``.

Both the acceleration and the force output have direct feedthrough from ``u`` (Eqs. 18, 45).

Coupling conditions at T_{N+1} are differences "mass 2 minus mass 1" of one output:

* kinematic, on position, velocity and acceleration level: ``x2 - x1``, ``v2 - v1``, ``v2' - v1'``
  (Eqs. 7c, 25–27, 47–49); which level or combination of levels is used is the coupling method's
  choice (``implicit_coupling_laws``);
* force: ``f2 - f1``, i.e. ``mu_2 - lambda_c`` (Eq. 33c: the force output of the force-driven mass is
  its input ``lambda_c``) or ``mu_2 - mu_1`` (Eq. 57c).

Force/force has only the kinematic condition (the force condition holds identically), displacement/
displacement only the force condition (both masses follow the same acceleration, so the kinematic
gaps vanish identically), force/displacement has both, one per coupling variable.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.compensation.implicit.two_mass_test_model import COUPLING_SIGNS

KINEMATIC_LEVELS = slice(0, 3)  # position, velocity, acceleration rows of the outputs
FORCE_LEVEL = 3


@dataclass(frozen=True)
class LinearBody:
    """One mass as a linear subsystem: ``z' = A z + B u``, outputs ``y = C z + D u`` (see module docstring)."""

    A: np.ndarray  # 2 x 2
    B: np.ndarray  # 2
    C: np.ndarray  # 4 x 2
    D: np.ndarray  # 4


def force_driven_body(mass: float, stiffness: float, damping: float, sign: float) -> LinearBody:
    """A mass driven by the coupling force (Eqs. 7a, 7b, 33a)."""
    acceleration_row = np.array([-stiffness / mass, -damping / mass])
    return LinearBody(
        A=np.vstack([[0.0, 1.0], acceleration_row]),
        B=np.array([0.0, sign / mass]),
        C=np.vstack([np.eye(2), acceleration_row, [0.0, 0.0]]),
        D=np.array([0.0, 0.0, sign / mass, 1.0]),
    )


def displacement_driven_body(mass: float, stiffness: float, damping: float, sign: float) -> LinearBody:
    """A mass whose acceleration is prescribed; its force output is the multiplier mu (Eqs. 33b, 57)."""
    return LinearBody(
        A=np.array([[0.0, 1.0], [0.0, 0.0]]),
        B=np.array([0.0, 1.0]),
        C=np.vstack([np.eye(2), [0.0, 0.0], [sign * stiffness, sign * damping]]),
        D=np.array([0.0, 0.0, 1.0, sign * mass]),
    )


_BODY_BUILDERS = {"force": force_driven_body, "displacement": displacement_driven_body}


@dataclass(frozen=True)
class LinearisedCouplingConditions:
    """The coupling conditions at T_{N+1} as linear functions of the coupling variables ``e*``.

    ``g(e*) = residual + jacobian @ (e* - e^p)`` (Eqs. 15, 41, 42, 47–49, 65), one row per output
    level (position, velocity, acceleration, force). Exact for the linear test model, a Newton
    linearisation otherwise. ``kinematic`` and ``force`` say which conditions the decomposition has.

    A joint on a line has ``jacobian`` (4, n_e) and ``residual`` (4, ...), whose trailing axis is carried
    through (the recurrence passes one column per state). A joint with ``d`` axes (a point in the
    plane, d = 2) has ``jacobian`` (4, d, n_e) and ``residual`` (4, d): every condition holds per axis,
    so each level contributes ``d`` rows, and ``n_e`` is ``d`` times the number of coupling variables.
    """

    residual: np.ndarray  # (4, ...) or (4, d): output of mass 2 minus output of mass 1 after the predictor run
    jacobian: np.ndarray  # (4, n_e) or (4, d, n_e): derivative of that difference w.r.t. the coupling variables
    kinematic: bool
    force: bool

    def root(self, predicted_coupling: np.ndarray, kinematic_weights: tuple[float, float, float]) -> np.ndarray:
        """Coupling variables that zero the force condition and the kinematic condition
        ``w_pos g_pos + w_vel g_vel + w_acc g_acc`` (Eqs. 16, 25–27, 43, 50–52, 66), on every axis."""
        weights = np.asarray(kinematic_weights, dtype=float)
        on_axes = self.jacobian.ndim == 3
        residual = self.residual if on_axes else self.residual[:, None]  # (4, d, ...)
        jacobian = self.jacobian if on_axes else self.jacobian[:, None]  # (4, d, n_e)
        residual_rows, jacobian_rows = [], []
        if self.kinematic:
            residual_rows.append(np.tensordot(weights, residual[KINEMATIC_LEVELS], axes=1))
            jacobian_rows.append(np.tensordot(weights, jacobian[KINEMATIC_LEVELS], axes=1))
        if self.force:
            residual_rows.append(residual[FORCE_LEVEL])
            jacobian_rows.append(jacobian[FORCE_LEVEL])
        return predicted_coupling - np.linalg.solve(np.concatenate(jacobian_rows), np.concatenate(residual_rows))


@dataclass(frozen=True)
class Decomposition:
    """How the test model is cut into two subsystems and which coupling variables cross the cut."""

    name: str
    drives: tuple[str, str]  # "force" or "displacement", for mass 1 and mass 2
    coupling_variables: tuple[str, ...]  # names of the coupling variables e, in order
    coupling_index: tuple[int, int]  # which coupling variable is the input of mass 1 and of mass 2
    kinematic: bool  # has the kinematic coupling condition
    force: bool  # has the force coupling condition

    def bodies(
        self, masses: tuple[float, float], stiffnesses: tuple[float, float], dampings: tuple[float, float]
    ) -> tuple[LinearBody, LinearBody]:
        """The two subsystems, in any consistent units (the recurrence uses the dimensionless ones)."""
        return tuple(
            _BODY_BUILDERS[drive](m, c, d, s)
            for drive, m, c, d, s in zip(self.drives, masses, stiffnesses, dampings, COUPLING_SIGNS)
        )

    @property
    def reaction_bodies(self) -> tuple[int, ...]:
        """Masses whose force output is a multiplier ``mu_i`` of their own (0-based)."""
        return tuple(i for i, drive in enumerate(self.drives) if drive == "displacement")

    def linearised_conditions(
        self, predicted_outputs: np.ndarray, output_sensitivity: np.ndarray
    ) -> LinearisedCouplingConditions:
        """The coupling conditions from what the subsystems report after the predictor run.

        ``predicted_outputs`` (2, 4, ...): outputs ``y`` of mass 1 and mass 2 at T_{N+1} of the
        predictor run; ``output_sensitivity`` (2, 4, n_e): their derivatives w.r.t. the coupling
        variables at T_{N+1} (Eqs. 13, 39, 63; zero for a variable that is not the mass's input).
        A joint with ``d`` axes passes (2, 4, d) and (2, 4, d, n_e) (see ``LinearisedCouplingConditions``).
        """
        return LinearisedCouplingConditions(
            residual=predicted_outputs[1] - predicted_outputs[0],
            jacobian=output_sensitivity[1] - output_sensitivity[0],
            kinematic=self.kinematic,
            force=self.force,
        )


FORCE_FORCE = Decomposition(
    name="force-force",
    drives=("force", "force"),
    coupling_variables=("lambda_c",),
    coupling_index=(0, 0),
    kinematic=True,
    force=False,
)
FORCE_DISPLACEMENT = Decomposition(
    name="force-displacement",
    drives=("force", "displacement"),
    coupling_variables=("lambda_c", "a_1"),
    coupling_index=(0, 1),
    kinematic=True,
    force=True,
)
DISPLACEMENT_DISPLACEMENT = Decomposition(
    name="displacement-displacement",
    drives=("displacement", "displacement"),
    coupling_variables=("a_tilde",),
    coupling_index=(0, 0),
    kinematic=False,
    force=True,
)

DECOMPOSITIONS = {d.name: d for d in (FORCE_FORCE, FORCE_DISPLACEMENT, DISPLACEMENT_DISPLACEMENT)}


def resolve_decomposition(decomposition: str | Decomposition) -> Decomposition:
    """A registered decomposition by name (``DECOMPOSITIONS``), or the instance itself."""
    if isinstance(decomposition, Decomposition):
        return decomposition
    try:
        return DECOMPOSITIONS[decomposition]
    except KeyError:
        raise ValueError(
            f"unknown decomposition {decomposition!r}; expected one of {', '.join(DECOMPOSITIONS)}"
        ) from None
