"""Fixed-step integrators. One class per method; ``INTEGRATORS`` maps scene names to classes.

An integrator is bound to one model and one state vector ``z`` (updated in place) and advances it by
one micro-step ``h`` with the inputs evaluated where the method needs them. Second-order models
(``model.second_order``) have ``z = [x, v]`` and give the acceleration; first-order models (a
hydraulic circuit) give ``ż`` itself. Symplectic Euler needs the second-order form.

For a linear second-order model ``a = A_a z + B_a w`` every method is also a linear map (the exact
discrete analysis, ``manager.discrete``, is built from it):

    z⁺ = Φ z + Σ_i Γ_i w(τ + θ_i h),   θ_i = ``input_nodes[i]``,

given by the class method ``linear_step(A_a, B_a, h) -> (Φ, Γ)`` with ``Γ`` of shape
``(len(input_nodes), 2n, n_inputs)``. External forces of time are not part of it.
``composed_linear_step`` composes it over the micro-steps of a communication step.
"""
from __future__ import annotations

import numpy as np

from subsystems.exact_integrator import ExactLinear
from subsystems.inputs import InputPolynomial


def composed_linear_step(integrator_cls: type, A_a: np.ndarray, B_a: np.ndarray, h: float, micro_steps: int,
                         rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The map of ``micro_steps`` steps ``h`` of ``integrator_cls`` over an input polynomial
    ``w(τ) = Σ_r c_r τ^r`` of ``rows`` coefficients (``τ`` from the start of the first micro-step)::

        z_m = Φ^m z_0 + Σ_r Ψ_r c_r,   Ψ_r = Σ_j Σ_i Φ^{m-1-j} Γ_i (τ_j + θ_i h)^r,

    returned as ``(Φ^m, Ψ)`` with ``Ψ`` of shape ``(2n, rows, n_inputs)``. Both the runtime
    (``subsystems.subsystem``) and the exact discrete analysis (``manager.discrete``) use it."""
    Phi, Gamma = integrator_cls.linear_step(A_a, B_a, h)
    nodes = np.asarray(integrator_cls.input_nodes) * h
    Phi_m = np.eye(Phi.shape[0])
    Psi = np.zeros((Phi.shape[0], rows, B_a.shape[1]))
    for j in range(micro_steps):  # Horner: Ψ ← Φ Ψ + Σ_i Γ_i (τ_j + θ_i h)^r
        powers = (j * h + nodes)[:, None] ** np.arange(rows)[None, :]  # (nodes, rows)
        Psi = np.einsum("ab,brk->ark", Phi, Psi) + np.einsum("iak,ir->ark", Gamma, powers)
        Phi_m = Phi @ Phi_m
    return Phi_m, Psi


def state_derivative(model, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``ż`` at time t [s] with input values ``w``: ``[v, a]`` for a second-order model."""
    if model.second_order:
        return np.concatenate((z[model.n_dof:], model.acceleration(t, z, w)))
    return model.derivative(t, z, w)


class SymplecticEuler:
    """Kick–drift symplectic Euler: ``v⁺ = v + h a(t, x, v, u(t))``, ``x⁺ = x + h v⁺``.

    The papers' integrator (paper 000 §5.1, paper 002 §3.3); first order, one acceleration per step.
    """

    name = "symplectic_euler"
    second_order_only = True
    input_nodes = (0.0,)

    @staticmethod
    def linear_step(A_a: np.ndarray, B_a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Γ)`` of one kick–drift step: ``v⁺`` rows ``[0 I] + h A_a``, ``x⁺`` rows ``[I 0] + h v⁺``."""
        n = A_a.shape[0]
        kick = np.hstack((np.zeros((n, n)), np.eye(n))) + h * A_a
        drift = np.hstack((np.eye(n), np.zeros((n, n)))) + h * kick
        return np.vstack((drift, kick)), np.vstack((h * h * B_a, h * B_a))[None]

    def __init__(self, model, z: np.ndarray) -> None:
        n = model.n_dof
        self.model = model
        self.z = z
        self.x = z[:n]
        self.v = z[n:]

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        v = self.v
        v += h * self.model.acceleration(t, self.z, inputs.at(tau))
        self.x += h * v


class RungeKutta4:
    """Classical fourth-order Runge–Kutta on ``ż = f(t, z, u(t))``; inputs at t, t + h/2, t + h."""

    name = "rk4"
    second_order_only = False
    input_nodes = (0.0, 0.5, 1.0)

    @staticmethod
    def linear_step(A_a: np.ndarray, B_a: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Γ)`` of one RK4 step on ``z' = F z + G w``, ``F = [[0, I], A_a]``, ``G = [[0], B_a]``.

        Each stage is a matrix on ``[z, w(τ), w(τ + h/2), w(τ + h)]``.
        """
        n, n_in = A_a.shape[0], B_a.shape[1]
        F = np.vstack((np.hstack((np.zeros((n, n)), np.eye(n))), A_a))
        G = np.vstack((np.zeros((n, n_in)), B_a))
        width = 2 * n + 3 * n_in
        z = np.eye(2 * n, width)

        def derivative(state: np.ndarray, node: int) -> np.ndarray:
            k = F @ state
            k[:, 2 * n + node * n_in:2 * n + (node + 1) * n_in] += G
            return k

        k1 = derivative(z, 0)
        k2 = derivative(z + 0.5 * h * k1, 1)
        k3 = derivative(z + 0.5 * h * k2, 1)
        k4 = derivative(z + h * k3, 2)
        step = z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        Gamma = np.stack([step[:, 2 * n + i * n_in:2 * n + (i + 1) * n_in] for i in range(3)])
        return step[:, :2 * n], Gamma

    def __init__(self, model, z: np.ndarray) -> None:
        self.model = model
        self.z = z

    def _derivative(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return state_derivative(self.model, t, z, w)

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        z = self.z
        half = 0.5 * h
        w_mid = inputs.at(tau + half)
        k1 = self._derivative(t, z, inputs.at(tau))
        k2 = self._derivative(t + half, z + half * k1, w_mid)
        k3 = self._derivative(t + half, z + half * k2, w_mid)
        k4 = self._derivative(t + h, z + h * k3, inputs.at(tau + h))
        z += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


INTEGRATORS: dict[str, type] = {cls.name: cls for cls in (SymplecticEuler, RungeKutta4, ExactLinear)}
