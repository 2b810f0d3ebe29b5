"""What every integrator shares: the state derivative of a model, and the composed linear map of a
communication step (the runtime's fast path for linear models and the exact discrete analysis)."""
from __future__ import annotations

import numpy as np


def composed_linear_step(integrator_cls: type, A_a: np.ndarray, B_a: np.ndarray, h: float, micro_steps: int,
                         rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The map of ``micro_steps`` steps ``h`` of ``integrator_cls`` over an input polynomial
    ``w(τ) = Σ_r c_r τ^r`` of ``rows`` coefficients (``τ`` from the start of the first micro-step)::

        z_m = Φ^m z_0 + Σ_r Ψ_r c_r,   Ψ_r = Σ_j Σ_i Φ^{m-1-j} Γ_i (τ_j + θ_i h)^r,

    returned as ``(Φ^m, Ψ)`` with ``Ψ`` of shape ``(2n, rows, n_inputs)``. Both the runtime
    (``subsystems.subsystem``) and the exact discrete analysis (``manager.analysis.discrete``) use it."""
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
