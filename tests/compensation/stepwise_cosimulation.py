"""Step-by-step co-simulation of the two-mass test model in SI units, as a runtime would run it.

Independent of the recurrence builder: its own physics of the two masses, time in seconds, Lagrange
polynomials fitted through the physical macro-time points, each mass integrated exactly over one
macro-step by ``scipy.linalg.expm`` of the mass augmented with the input polynomial, and the
derivatives of the outputs w.r.t. the coupling variables taken from a perturbed corrector run (a
finite difference, exact up to rounding for a linear model). Shared with the recurrence are only the
coupling law (``corrected_coupling``) and the projection step, which is the point: one
implementation of each method's coupling law.
"""
from __future__ import annotations

from math import factorial

import numpy as np
from numpy.polynomial import polynomial
from scipy.linalg import expm

from zencosim.compensation.implicit.coupling_laws import Baumgarte, corrected_coupling, project_onto_constraint
from zencosim.compensation.implicit.decompositions import Decomposition
from zencosim.compensation.implicit.two_mass_test_model import DimensionlessTwoMass


class Mass:
    """One mass, ``m a = -c x - d v + sign f``, driven by a force ``f`` or by a prescribed acceleration."""

    def __init__(self, mass, stiffness, damping, sign, drive, macro_step, degree):
        self.mass, self.stiffness, self.damping, self.sign, self.drive = mass, stiffness, damping, sign, drive
        if drive == "force":
            A = np.array([[0.0, 1.0], [-stiffness / mass, -damping / mass]])
            B = np.array([0.0, sign / mass])
        else:
            A = np.array([[0.0, 1.0], [0.0, 0.0]])
            B = np.array([0.0, 1.0])
        size = 2 + degree + 1
        augmented = np.zeros((size, size))
        augmented[:2, :2] = A
        augmented[:2, 2] = B
        for i in range(degree):
            augmented[2 + i, 3 + i] = 1.0  # chain of integrators generating the input polynomial
        self.exponential = expm(augmented * macro_step)[:2]
        self.taylor = np.array([factorial(i) for i in range(degree + 1)], dtype=float)

    def advance(self, state, input_coefficients):
        """State after one macro-step with input ``u(tau) = sum_i c_i tau**i``, tau in [0, H]."""
        return self.exponential @ np.concatenate([state, self.taylor * input_coefficients])

    def outputs(self, state, input_value):
        """Position, velocity, acceleration and coupling force on the mass."""
        x, v = state
        if self.drive == "force":
            acceleration = (-self.stiffness * x - self.damping * v + self.sign * input_value) / self.mass
            force = input_value
        else:
            acceleration = input_value
            force = self.sign * (self.mass * acceleration + self.stiffness * x + self.damping * v)
        return np.array([x, v, acceleration, force])


class StepwiseCosimulation:
    """The predictor -> coupling law -> corrector (-> projection) loop of paper 003, §2, in SI units."""

    def __init__(self, method, decomposition: Decomposition, k, model: DimensionlessTwoMass, macro_step, mass_1):
        H = macro_step
        self.decomposition, self.k, self.macro_step, self.mass_1 = decomposition, k, H, mass_1
        self.method = Baumgarte(method.beta * H, method.gamma * H**2) if isinstance(method, Baumgarte) else method
        self.masses = (mass_1, model.alpha_m21 * mass_1)
        stiffnesses = [c_bar * mass_1 / H**2 for c_bar in model.stiffnesses]
        dampings = [d_bar * mass_1 / H for d_bar in model.dampings]
        self.bodies = [
            Mass(m, c, d, s, drive, H, k)
            for m, c, d, s, drive in zip(self.masses, stiffnesses, dampings, (1.0, -1.0), decomposition.drives)
        ]
        self.inputs = decomposition.coupling_index
        # a coupling variable is a force if it drives a force-driven mass, else an acceleration
        self.coupling_is_force = [
            any(decomposition.drives[b] == "force" and self.inputs[b] == e for b in range(2))
            for e in range(len(decomposition.coupling_variables))
        ]
        self.predictor_times = -H * np.arange(k + 1)
        self.corrector_times = H - H * np.arange(k + 1)
        self.states = np.zeros((2, 2))
        self.coupling_history = np.zeros((k + 1, len(decomposition.coupling_variables)))
        self.corrector_outputs = np.zeros((2, 4))  # outputs at T_{N+1} of the corrector run, before projection

    # --- dimensionless view (Eq. 5/6 scaling with l = 1 m) -------------------------------------
    def _coupling_scale(self):
        H = self.macro_step
        return np.array([H**2 / self.mass_1 if is_force else H**2 for is_force in self.coupling_is_force])

    def set_dimensionless(self, states, coupling_history):
        """``states`` (2, 2): (x_bar, v_bar) of each mass; ``coupling_history`` (k + 1, n_e), newest first."""
        self.states = np.array(states, dtype=float) / np.array([1.0, self.macro_step])
        self.coupling_history = np.array(coupling_history, dtype=float) / self._coupling_scale()

    def dimensionless_state(self):
        """``z_hat`` in the order of ``implicit_recurrence.recurrence_variables``."""
        H = self.macro_step
        kinematic = self.states * np.array([1.0, H])
        states = kinematic[0] if self.method.projects_states else kinematic.ravel()
        multipliers = self.corrector_outputs[list(self.decomposition.reaction_bodies), 3] * H**2 / self.mass_1
        return np.concatenate([states, multipliers, self.coupling_history[0] * self._coupling_scale()])

    def scale(self, factor):
        """Multiply every state and coupling value by ``factor`` (allowed: the model is linear)."""
        self.states *= factor
        self.coupling_history *= factor
        self.corrector_outputs *= factor

    # --- one macro-step --------------------------------------------------------------------------
    def _fit(self, node_times, node_values):
        """Monomial coefficients (in tau = t - T_N) of the Lagrange polynomial of each coupling variable
        through ``node_values`` (k + 1, n_e): the Vandermonde system in physical time."""
        return np.linalg.solve(np.vander(node_times, increasing=True), node_values)

    def _run(self, coefficients):
        """Integrate both masses from T_N with input polynomials ``coefficients`` (k + 1, n_e)."""
        end_states, outputs = [], []
        for body, state, e in zip(self.bodies, self.states, self.inputs):
            end_state = body.advance(state, coefficients[:, e])
            end_states.append(end_state)
            outputs.append(body.outputs(end_state, polynomial.polyval(self.macro_step, coefficients[:, e])))
        return np.array(end_states), np.array(outputs)

    def step(self):
        """One macro-step: predictor, coupling law, corrector from the same T_N, projection."""
        history = self.coupling_history
        predictor = self._fit(self.predictor_times, history)
        _, predicted_outputs = self._run(predictor)
        predicted_coupling = polynomial.polyval(self.macro_step, predictor)
        sensitivity = np.zeros((2, 4, history.shape[1]))
        for e in range(history.shape[1]):
            perturbation = 1.0 + abs(predicted_coupling[e])
            perturbed = np.vstack([predicted_coupling, history[:-1]])
            perturbed[0, e] += perturbation
            _, perturbed_outputs = self._run(self._fit(self.corrector_times, perturbed))
            sensitivity[:, :, e] = (perturbed_outputs - predicted_outputs) / perturbation
        coupling_new = corrected_coupling(self.method, self.decomposition, history, predicted_outputs, sensitivity)
        self.coupling_history = np.vstack([coupling_new, history[:-1]])
        end_states, outputs = self._run(self._fit(self.corrector_times, self.coupling_history))
        if self.method.projects_states:
            position, velocity = project_onto_constraint(end_states[:, 0], end_states[:, 1], self.masses)
            end_states = np.array([[position, velocity]] * 2)
        self.states = end_states
        self.corrector_outputs = outputs
