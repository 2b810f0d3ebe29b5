"""Convergence study of the implicit co-simulation methods (paper 003, §3.7).

The co-simulation results are obtained by iterating the recurrence system of the method
(``implicit_recurrence``; subsystems integrated exactly, so the error is the coupling error alone),
started at T_0 from the analytic solution: ``z_hat_0, z_hat_{-1}, ..., z_hat_{-k}`` are the exact
states, multipliers and coupling variables at T_0, T_{-1}, ..., T_{-k} (the analytic solution
continued to negative times). The paper does not say how it starts a degree-k predictor; this
start introduces no error of its own, so the measured order is that of the coupling method.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.compensation.implicit.coupling_laws import CouplingMethod
from zencosim.compensation.implicit.decompositions import Decomposition
from zencosim.compensation.implicit.recurrence import build_recurrence
from zencosim.compensation.implicit.two_mass_test_model import TwoMassOscillator


@dataclass(frozen=True)
class ConvergenceStudy:
    """Global errors (Eq. 72) over macro-step sizes and the fitted order."""

    macro_steps: np.ndarray  # H [s]
    global_errors: np.ndarray  # epsilon_glo [-]
    slope: float  # least-squares slope of log(epsilon_glo) over log(H)


def global_error(
    method: CouplingMethod,
    decomposition: str | Decomposition,
    k: int,
    model: TwoMassOscillator,
    macro_step: float,
    end_time: float,
    position_0: float,
    velocity_0: float,
    window_start: float = 0.0,
) -> float:
    """Relative global error ``epsilon_glo`` of Eq. (72) at the macro-time points T_1, ..., T_end.

    ``method`` carries its parameters in seconds (``Baumgarte.from_mu`` with the paper's
    non-dimensionless ``beta = 2 mu``, ``gamma = mu^2`` of the §3.7.1 remark); it is converted to
    macro-step units for each ``H``. ``end_time`` must be a whole number of macro-steps.

    With ``window_start`` [s] > 0 only the points ``T_N >= window_start`` enter Eq. (72): this
    separates the error that a start-up transient leaves in the first few macro-steps from the
    error of the smooth numerical solution.
    """
    n_steps = round(end_time / macro_step)
    if not np.isclose(n_steps * macro_step, end_time, rtol=1e-9, atol=0.0):
        raise ValueError(f"end_time {end_time} s is not a whole number of macro-steps of {macro_step} s")
    recurrence = build_recurrence(method.in_macro_step_units(macro_step), decomposition, k, model.dimensionless(macro_step))
    n = len(recurrence.variables)
    times = macro_step * np.arange(-k, n_steps + 1)
    exact = _exact_recurrence_states(recurrence.variables, model, macro_step, model.monolithic_solution(position_0, velocity_0, times))

    companion = recurrence.companion_matrix()
    history = exact[k::-1].ravel()  # z_hat_0, z_hat_{-1}, ..., z_hat_{-k}
    simulated = np.empty((n_steps, n))
    for step in range(n_steps):
        history = companion @ history
        simulated[step] = history[:n]

    first = max(1, int(np.ceil(window_start / macro_step - 1e-9)))  # first N with T_N >= window_start, up to rounding
    reference = exact[k + first :]
    simulated = simulated[first - 1 :]
    index = {name: i for i, name in enumerate(recurrence.variables)}
    kinematic = ("x1", "x2", "v1", "v2") if "x1" in index else ("x", "x", "v", "v")
    squared = 0.0
    for name in kinematic:
        ref, sim = reference[:, index[name]], simulated[:, index[name]]
        squared += np.sum((ref - sim) ** 2) / np.sum((ref - ref.mean()) ** 2)
    return float(np.sqrt(squared))


def convergence_study(
    method: CouplingMethod,
    decomposition: str | Decomposition,
    k: int,
    model: TwoMassOscillator,
    macro_steps: np.ndarray,
    end_time: float,
    position_0: float,
    velocity_0: float,
    window_start: float = 0.0,
) -> ConvergenceStudy:
    """``global_error`` for every macro-step size and the least-squares slope on log-log axes."""
    macro_steps = np.asarray(macro_steps, dtype=float)
    errors = np.array(
        [
            global_error(method, decomposition, k, model, H, end_time, position_0, velocity_0, window_start)
            for H in macro_steps
        ]
    )
    slope = np.polyfit(np.log(macro_steps), np.log(errors), 1)[0]
    return ConvergenceStudy(macro_steps, errors, float(slope))


def _exact_recurrence_states(
    variables: tuple[str, ...], model: TwoMassOscillator, macro_step: float, solution: tuple[np.ndarray, ...]
) -> np.ndarray:
    """The analytic solution as dimensionless recurrence states (Eq. 5/6 scaling, l = 1 m), one row per time.

    Both masses move together; every coupling force (``lambda_c``, ``mu_1``, ``mu_2``, with the sign
    convention of ``coupling_decompositions``) equals the multiplier, every prescribed acceleration
    (``a_1``, ``a_tilde``) the acceleration.
    """
    position, velocity, acceleration, multiplier = solution
    force_bar = multiplier * macro_step**2 / model.m1
    velocity_bar = velocity * macro_step
    acceleration_bar = acceleration * macro_step**2
    by_name = {
        **dict.fromkeys(("x", "x1", "x2"), position),
        **dict.fromkeys(("v", "v1", "v2"), velocity_bar),
        **dict.fromkeys(("mu1", "mu2", "lambda_c"), force_bar),
        **dict.fromkeys(("a_1", "a_tilde"), acceleration_bar),
    }
    return np.column_stack([by_name[name] for name in variables])
