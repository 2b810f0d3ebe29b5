"""Fixed-step integrators. One class per method; ``INTEGRATORS`` maps scene names to classes.

An integrator is bound to one model and one state vector ``z`` (updated in place) and advances it by
one micro-step ``h`` with the inputs evaluated where the method needs them. Second-order models
(``model.second_order``) have ``z = [x, v]`` and give the acceleration; first-order models (a
hydraulic circuit) give ``ż`` itself. Symplectic Euler needs the second-order form.

For a linear second-order model ``a = A_a z + B_a w`` every method is also a linear map (the exact
discrete analysis, ``manager.analysis.discrete``, is built from it):

    z⁺ = Φ z + Σ_i Γ_i w(τ + θ_i h),   θ_i = ``input_nodes[i]``,

given by the class method ``linear_step(A_a, B_a, h) -> (Φ, Γ)`` with ``Γ`` of shape
``(len(input_nodes), 2n, n_inputs)``. External forces of time are not part of it.
``composed_linear_step`` composes it over the micro-steps of a communication step. ``own`` is not an
integrator of zencosim's: a co-simulation FMU advances itself.
"""
from zencosim.subsystems.integrators.exact import ExactLinear
from zencosim.subsystems.integrators.own_solver import OwnSolver
from zencosim.subsystems.integrators.runge_kutta import RungeKutta4
from zencosim.subsystems.integrators.symplectic_euler import SymplecticEuler

INTEGRATORS: dict[str, type] = {cls.name: cls for cls in (SymplecticEuler, RungeKutta4, ExactLinear, OwnSolver)}
