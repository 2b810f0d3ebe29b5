"""System of recurrence equations of an implicit co-simulation method on the test model (paper 003,
Eqs. 20–23, 31–32, 46, 56, 70) and its spectral radius.

Recurrence state ``z_hat`` (newest values at T_{N+1}):

* Baumgarte, weighted multiplier: ``(x1, v1, x2, v2, mu..., e...)`` — Eq. (20): 5 variables for
  force/force, Eq. (46): 7 for force/displacement;
* projection: ``(x, v, mu..., e...)`` with the projected position and velocity — Eq. (31): 3 for
  force/force, Eq. (56): 5 for force/displacement, Eq. (70): 5 for displacement/displacement;

where ``mu...`` are the multipliers of the displacement-driven masses and ``e...`` the coupling
variables of the decomposition.

Construction. One macro-step is a linear map of the history ``h_N = (z_hat_N, ..., z_hat_{N-k})``.
Every quantity of the step is carried as a matrix with one column per entry of ``h_N`` (the linear
functional that gives it), and the step is run once on these matrices: predictor (Eq. 9),
``corrected_coupling`` — the same coupling law a runtime calls with numbers — corrector (Eq. 11) and
the projection step (Eq. 30). The subsystems are integrated exactly (``macro_step_response``). This
gives ``z_hat_{N+1} = sum_j R_j z_hat_{N-j}``, Eq. (21) solved for the newest values:
``A_{N+1} = I``, ``A_{N-j} = -R_j``.

Spectral radius. Eq. (22) with ``z_hat_N = Z lambda^N`` leads to the polynomial eigenvalue problem
``det(lambda^{k+1} I - R_0 lambda^k - ... - R_k) = 0`` (Eq. 23). Its block-companion linearisation
is the one-step map of ``h_N``::

    h_{N+1} = [[R_0, R_1, ..., R_{k-1}, R_k],
               [I,   0,   ..., 0,       0  ],
               [0,   I,   ..., 0,       0  ],
               ...
               [0,   0,   ..., I,       0  ]] h_N

whose ``n (k + 1)`` eigenvalues are exactly the roots of Eq. (23) (``n`` recurrence variables). The
state variables and multipliers enter the step only through ``z_hat_N`` (they are initial conditions),
so their columns in ``R_1 ... R_k`` are zero and they add only zero eigenvalues, as do the outputs
``mu`` that nothing reads; the spectral radius ``rho = max |lambda_j|`` (§1) is unaffected. The
method is stable when ``rho <= 1``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.compensation.implicit.coupling_laws import (
    CouplingMethod,
    check_supported,
    corrected_coupling,
    project_onto_constraint,
)
from zencosim.compensation.implicit.decompositions import FORCE_LEVEL, Decomposition, LinearBody, resolve_decomposition
from zencosim.compensation.implicit.two_mass_test_model import DimensionlessTwoMass
from zencosim.compensation.lagrange_polynomials import (
    basis_coefficients,
    basis_values,
    corrector_nodes,
    predictor_nodes,
)
from zencosim.compensation.macro_step_response import polynomial_input_response


@dataclass(frozen=True)
class RecurrenceSystem:
    """``z_hat_{N+1} = sum_j R_j z_hat_{N-j}`` (Eq. 21 with ``A_{N+1} = I``, ``A_{N-j} = -R_j``)."""

    variables: tuple[str, ...]  # names of the entries of z_hat
    coefficients: np.ndarray  # (k + 1, n, n): R_0, ..., R_k

    @property
    def k(self) -> int:
        return len(self.coefficients) - 1

    def companion_matrix(self) -> np.ndarray:
        """The block-companion linearisation of Eq. (23) (module docstring): ``h_{N+1} = M h_N``."""
        n = len(self.variables)
        size = n * (self.k + 1)
        companion = np.zeros((size, size))
        companion[:n] = np.hstack(list(self.coefficients))
        companion[n:, :-n] = np.eye(size - n)
        return companion

    def eigenvalues(self) -> np.ndarray:
        """The ``n (k + 1)`` roots of the characteristic equation (23)."""
        return np.linalg.eigvals(self.companion_matrix())

    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.eigenvalues())))


def recurrence_variables(method: CouplingMethod, decomposition: Decomposition) -> tuple[str, ...]:
    """Names of the entries of ``z_hat`` (module docstring)."""
    states = ("x", "v") if method.projects_states else ("x1", "v1", "x2", "v2")
    multipliers = tuple(f"mu{i + 1}" for i in decomposition.reaction_bodies)
    return states + multipliers + decomposition.coupling_variables


def build_recurrence(
    method: CouplingMethod, decomposition: str | Decomposition, k: int, model: DimensionlessTwoMass
) -> RecurrenceSystem:
    """The recurrence system of ``method`` on ``decomposition`` with Lagrange degree ``k`` for the test
    model ``model``. ``method`` must be in macro-step units (``beta_bar``, ``gamma_bar`` for Baumgarte)."""
    decomposition = resolve_decomposition(decomposition)
    check_supported(method, decomposition)
    variables = recurrence_variables(method, decomposition)
    n = len(variables)
    index = {name: i for i, name in enumerate(variables)}
    history = np.eye(n * (k + 1)).reshape(k + 1, n, n * (k + 1))  # z_hat_{N-j} as functionals of h_N

    if method.projects_states:
        initial_states = [history[0, [index["x"], index["v"]]]] * 2
    else:
        initial_states = [history[0, [index["x1"], index["v1"]]], history[0, [index["x2"], index["v2"]]]]
    coupling_rows = [index[name] for name in decomposition.coupling_variables]
    coupling_history = history[:, coupling_rows]  # (k + 1, n_e, columns): e_N, ..., e_{N-k}

    bodies = decomposition.bodies(model.masses, model.stiffnesses, model.dampings)
    steps = [_BodyMacroStep(body, k) for body in bodies]
    inputs = decomposition.coupling_index

    predicted_outputs = np.array(
        [step.predictor_outputs(z0, coupling_history[:, e]) for step, z0, e in zip(steps, initial_states, inputs)]
    )
    sensitivity = np.zeros((2, 4, len(coupling_rows)))
    for body, (step, e) in enumerate(zip(steps, inputs)):
        sensitivity[body, :, e] = step.output_sensitivity()
    coupling_new = corrected_coupling(method, decomposition, coupling_history, predicted_outputs, sensitivity)

    corrector_inputs = np.concatenate([coupling_new[None], coupling_history[:-1]])  # e_{N+1}, e_N, ..., e_{N-k+1}
    corrected = [step.corrector(z0, corrector_inputs[:, e]) for step, z0, e in zip(steps, initial_states, inputs)]

    new = np.zeros((n, n * (k + 1)))
    if method.projects_states:
        positions = np.array([state[0] for state, _ in corrected])
        velocities = np.array([state[1] for state, _ in corrected])
        new[index["x"]], new[index["v"]] = project_onto_constraint(positions, velocities, model.masses)
    else:
        for body, (state, _) in enumerate(corrected):
            new[index[f"x{body + 1}"]], new[index[f"v{body + 1}"]] = state
    for body in decomposition.reaction_bodies:
        new[index[f"mu{body + 1}"]] = corrected[body][1][FORCE_LEVEL]  # mu_i of the corrector run (Eq. 54)
    new[coupling_rows] = coupling_new
    return RecurrenceSystem(variables, new.reshape(n, k + 1, n).transpose(1, 0, 2))


def spectral_radius(
    method: CouplingMethod, decomposition: str | Decomposition, k: int, model: DimensionlessTwoMass
) -> float:
    """Spectral radius of the recurrence system (Eq. 23); the method is stable for ``rho <= 1``."""
    return build_recurrence(method, decomposition, k, model).spectral_radius()


class _BodyMacroStep:
    """Exact end-of-step state and outputs of one mass for Lagrange inputs on the predictor and the
    corrector nodes (Eqs. 9–12), as linear maps of the initial state and the node values."""

    def __init__(self, body: LinearBody, k: int):
        self.body = body
        self.transition, monomial_response = polynomial_input_response(body.A, body.B, k)
        self.predictor_response = monomial_response @ basis_coefficients(predictor_nodes(k)).T
        self.corrector_response = monomial_response @ basis_coefficients(corrector_nodes(k)).T
        self.predictor_end_weights = basis_values(predictor_nodes(k), 1.0)

    def predictor_outputs(self, initial_state: np.ndarray, node_values: np.ndarray) -> np.ndarray:
        """Outputs at T_{N+1} for the extrapolation through ``e_N, ..., e_{N-k}`` (Eq. 9)."""
        state = self.transition @ initial_state + self.predictor_response @ node_values
        end_input = self.predictor_end_weights @ node_values
        return self.body.C @ state + np.multiply.outer(self.body.D, end_input)

    def output_sensitivity(self) -> np.ndarray:
        """Derivatives of the outputs at T_{N+1} w.r.t. the corrector node value ``e*_{N+1}`` (Eq. 13).

        The corrector polynomial is 1 at T_{N+1} on its first basis function, which feeds through ``D``.
        """
        return self.body.C @ self.corrector_response[:, 0] + self.body.D

    def corrector(self, initial_state: np.ndarray, node_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """State and outputs at T_{N+1} for the interpolation through ``e_{N+1}, e_N, ..., e_{N-k+1}`` (Eq. 11)."""
        state = self.transition @ initial_state + self.corrector_response @ node_values
        return state, self.body.C @ state + np.multiply.outer(self.body.D, node_values[0])
