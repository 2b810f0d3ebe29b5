"""The companion-form linearisation has exactly the roots of det T(s) with the Padé D(s)."""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.architecture import full_feedback, rank_one
from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.perturbation import cosimulated_stiffness
from zencosim.compensation.eigenstructure.realization import SingularMassError, realize


def _systems(two_mass, four_mass):
    """(name, model, T): uncompensated, and compensated with arbitrary gains (every D power used)."""
    rng = np.random.default_rng(7)
    out = []
    for name, model in (("two_mass", two_mass(0.1, 4e-3)), ("four_mass", four_mass())):
        out.append((name, model, cosimulated_stiffness(model)))
        for architecture in (full_feedback(model), rank_one(model)):
            k = 1e-2 * rng.standard_normal(architecture.n_gains)
            T = cosimulated_stiffness(model) + architecture.stiffness(k, model.n_dof)
            out.append((f"{name}+{architecture.name}", model, T))
    return out


@pytest.mark.parametrize("order", [0, 1, 2])
def test_eigenvalues_are_roots_and_only_roots(two_mass, four_mass, order):
    for name, model, T in _systems(two_mass, four_mass):
        D = InterfaceModel(order, model.macro_step).rational(6)
        space = realize(T, D)
        # One hold per exchanged signal (x_j sent to the force side, one bundled force sent back):
        # a minimal realization, so no spurious modes.
        assert space.holds == (f"motion:{model.bonds[0].motion_dof}", f"force:{model.bonds[0].motion_dof}"), name
        assert space.A.shape == (2 * model.n_dof + 2 * space.hold_order,) * 2, name
        for lam in space.eigenvalues():
            sv = np.linalg.svd(T(lam, D(lam)), compute_uv=False)
            # Roots: T(λ) singular to round-off, amplified by the repeated hold poles (Q^{q+1});
            # measured worst 1e-10 (ZOH), 3e-10 (FOH), 8e-9 (SOH).
            assert sv[-1] / sv[0] < 1e-7, (name, lam)
            # Only roots: a spurious mode of a non-minimal realization sits at a pole of D
            # (measured nearest distance 3e-3 |λ|).
            assert np.min(np.abs(D.poles() - lam)) > 1e-6 * abs(lam), (name, lam)


def test_zero_effective_mass_is_refused(two_mass):
    model = two_mass(0.1, 1e-3)
    architecture = full_feedback(model)
    k = np.zeros(architecture.n_gains)
    k[0] = -1.0  # d_1 = -m_1: mass 1 loses its inertia
    T = cosimulated_stiffness(model) + architecture.stiffness(k, model.n_dof)
    with pytest.raises(SingularMassError, match="effective mass matrix"):
        realize(T, InterfaceModel(0, model.macro_step).rational(6))
