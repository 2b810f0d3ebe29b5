"""References a run is compared with: the analytic solution and the monolithic run of the same scene.

Both are expressed through the monolithic model (``manager.build.build_monolithic``), whose outputs
are every coupling signal and the energy, so a signal is computed by the same output equations in
the co-simulation, the monolithic run and the analytic reference.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from compensation.analytic import linear_response
from manager.build import build_monolithic
from manager.scene import Scene
from subsystems.inputs import InputPolynomial


@dataclass(frozen=True)
class Reference:
    """Signals and energy of a reference on the base macro-step grid (``n_ticks + 1`` samples)."""

    kind: str
    signals: dict[str, np.ndarray]
    energy: np.ndarray


def _reference(kind: str, outputs: np.ndarray, ports) -> Reference:
    signals = {p.name: outputs[:, j] for j, p in enumerate(ports) if p.quantity != "energy"}
    return Reference(kind, signals, outputs[:, -1])


def analytic_reference(scene: Scene) -> Reference:
    """The exact solution of the monolithic linear system (matrix exponential, free and forced)."""
    mono = build_monolithic(scene)
    model = mono.model
    n = model.n_dof
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    Minv = np.linalg.inv(model.M)
    A[n:, :n] = -Minv @ model.K
    A[n:, n:] = -Minv @ model.C
    n_ticks = scene.manager.duration_ns // scene.manager.macro_step_ns
    step = scene.manager.macro_step_ns * 1e-9
    force = None
    B = None
    if model.external:
        B = np.zeros((2 * n, len(model.external)))
        for j, (_, body) in enumerate(model.external):
            B[n:, j] = Minv[:, body]
        force = lambda t: np.array([effect.force(t) for effect, _ in model.external])  # noqa: E731
    Z = linear_response(A, model.initial_state(), step, n_ticks, B, force)
    no_inputs = np.empty(0)
    outputs = np.array([model.outputs_at(k * step, z, no_inputs) for k, z in enumerate(Z)])
    return _reference("analytic", outputs, model.outputs)


def monolithic_reference(scene: Scene) -> Reference:
    """The monolithic system integrated with the subsystems' integrator (finest micro-step)."""
    mono = build_monolithic(scene)
    base = scene.manager.macro_step_ns
    n_ticks = scene.manager.duration_ns // base
    no_inputs = InputPolynomial(np.empty((1, 0)))
    outputs = np.empty((n_ticks + 1, len(mono.outputs)))
    outputs[0] = mono.output_values(np.empty(0))
    for k in range(n_ticks):
        outputs[k + 1] = mono.advance(k * base, (k + 1) * base, no_inputs)
    return _reference("monolithic", outputs, mono.outputs)
