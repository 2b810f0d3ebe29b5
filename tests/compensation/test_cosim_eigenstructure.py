"""Primary poles and latent roots of the co-simulated systems against Tables 1, 2, 7 and 8 of paper 000.

Tables print poles as ``re ± im j``; the tests compare the member with positive imaginary part
(``Eigenstructure`` orders each pair ``+im`` first) and check that the other is its conjugate.
"""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.modes import cosimulated_eigenstructure, monolithic_eigenstructure
from zencosim.compensation.eigenstructure.perturbation import (
    cosimulated_stiffness,
    interface_perturbation,
    monolithic_stiffness,
)

PADE_ORDER = 6  # §2.3.2: "6-th order Padé approximation"


def _cosim(model, extrapolation_order=0):
    monolithic = monolithic_eigenstructure(model)
    hold = InterfaceModel(extrapolation_order, model.macro_step)
    return monolithic, cosimulated_eigenstructure(cosimulated_stiffness(model), hold, PADE_ORDER, monolithic)


def _upper(poles):
    assert np.allclose(poles[1::2], np.conj(poles[::2]), rtol=1e-12)
    return poles[::2]


def _assert_close(poles, table, real_tol, imag_tol):
    """Real and imaginary parts compared separately, as the tables print them."""
    assert poles.real == pytest.approx(np.real(table), abs=real_tol)
    assert poles.imag == pytest.approx(np.imag(table), abs=imag_tol)


def test_monolithic_poles_of_tables_1_2_and_7(two_mass, four_mass):
    # Printed to two (Tables 1, 2) or three (Table 7) decimals: tolerance half a unit of the last digit.
    undamped, damped = (_upper(monolithic_eigenstructure(two_mass(c, 1e-3)).poles) for c in (0.0, 0.1))
    _assert_close(undamped, [10.00j, 33.32j], 0.005, 0.005)
    _assert_close(damped, [-0.09 + 10.00j, -0.11 + 33.32j], 0.005, 0.005)
    table_7 = [-0.002 + 6.586j, -0.009 + 13.120j, -0.017 + 18.206j, -0.023 + 21.479j]
    _assert_close(_upper(monolithic_eigenstructure(four_mass()).poles), table_7, 0.0005, 0.0005)


@pytest.mark.parametrize(
    "macro_step, table_2",
    [(1e-3, [-0.11 + 10.00j, -0.05 + 33.32j]), (4e-3, [-0.11 + 10.00j, 0.12 + 33.31j])],
)
def test_damped_two_mass_primary_poles_of_table_2(two_mass, macro_step, table_2):
    # Measured: 1 ms -0.0946+9.9995j, -0.0554+33.3174j; 4 ms -0.1079+9.9995j, +0.1075+33.3074j.
    # Tolerance of the brief: ±0.02 on the real part (the worst, 1 ms λ1,2, is off by 0.015),
    # ±0.01 on the imaginary part.
    _, cosim = _cosim(two_mass(0.1, macro_step))
    _assert_close(_upper(cosim.primary.poles), table_2, 0.02, 0.01)
    assert cosim.primary_converged.all()


def test_four_mass_primary_poles_of_table_7(four_mass):
    # Measured: -0.01177+6.58563j, 0.03045+13.11956j, 0.01749+18.20603j, 0.06323+21.47466j.
    # Real parts within ±0.002 of Table 7, and so are the imaginary parts of λ1..6. Reading taken:
    # the co-simulated imaginary parts printed in Table 7 equal the monolithic ones digit for
    # digit; for λ7,8 we get 21.4747, 0.0043 below the printed 21.479 (the exact-D Newton root
    # and the Padé root agree to 1e-12; first-order perturbation theory also predicts a downward
    # shift). That one entry is checked at ±0.005 and reported, not tuned.
    _, cosim = _cosim(four_mass())
    table_7 = np.array([-0.011 + 6.586j, 0.031 + 13.120j, 0.017 + 18.206j, 0.063 + 21.479j])
    poles = _upper(cosim.primary.poles)
    assert poles.real == pytest.approx(table_7.real, abs=0.002)
    assert poles.imag[:3] == pytest.approx(table_7.imag[:3], abs=0.002)
    assert poles.imag[3] == pytest.approx(table_7.imag[3], abs=0.005)


def test_four_mass_damping_ratios_of_table_8(four_mass):
    # Table 8 prints ξ to four decimals; measured 0.00179, -0.00232, -0.00096, -0.00294:
    # tolerance 1e-4 (two units of the last printed digit).
    monolithic, cosim = _cosim(four_mass())
    assert _upper(monolithic.xi + 0j).real == pytest.approx([0.0003, 0.0007, 0.0009, 0.0011], abs=1e-4)
    assert _upper(cosim.primary.xi + 0j).real == pytest.approx([0.0017, -0.0024, -0.0009, -0.0029], abs=1e-4)
    assert cosim.e_xi == pytest.approx(cosim.primary.xi - monolithic.xi)


def test_undamped_two_mass_follows_perturbation_theory_not_table_1(two_mass, four_mass):
    """Table 1 (undamped, 1 ms: -0.19 ± 9.51j, 0.52 ± 33.27j) is not reproduced.

    Measured: -0.00446 ± 10.00002j and +0.05444 ± 33.31557j (λ3,4 unstable, as the paper says).
    Independent check: the first-order shift ``δλ = -wᵀ ΔG_c(λ) w / wᵀ G_t'(λ) w`` (G_t symmetric,
    so wᵀ is the left eigenvector) predicts every co-simulated primary pole of the four benchmark
    systems to within 3 % of the shift; Table 1's λ1,2 shift (-0.19 - 0.49j) is a hundred times
    the predicted -0.0045.
    """
    models = [two_mass(0.0, 1e-3), two_mass(0.1, 1e-3), two_mass(0.1, 4e-3), four_mass()]
    for model in models:
        monolithic, cosim = _cosim(model)
        hold = InterfaceModel(0, model.macro_step)
        dG, G_t = interface_perturbation(model), monolithic_stiffness(model)
        for lam, w, lam_cosim in zip(monolithic.poles, monolithic.vectors.T, cosim.primary.poles):
            shift = -(w @ dG(lam, hold.D(lam)) @ w) / (w @ G_t.derivative(lam, 1.0, 0.0) @ w)
            assert abs(lam_cosim - lam - shift) <= 0.03 * abs(shift)
    _, undamped = _cosim(models[0])
    assert _upper(undamped.primary.poles) == pytest.approx([-0.00446 + 10.00002j, 0.05444 + 33.31557j], abs=1e-5)


def test_pade_and_exact_primary_poles_agree(two_mass):
    # At |λ T_s| <= 0.14 the order-6 Padé error is ~1e-13: polishing moves the roots by round-off.
    _, cosim = _cosim(two_mass(0.1, 4e-3))
    assert cosim.primary.poles == pytest.approx(cosim.primary_pade, abs=1e-9)


def test_mode_shapes_are_normalised_and_match_table_2_up_to_phase(two_mass):
    # The tables use unit norm and an arbitrary phase; compare the phase-free ratios. Table 2,
    # monolithic: w1,2 = [-0.097+0.990j, -0.011+0.099j], w3,4 = [0.0001-0.0995j, 0.0312+0.9945j];
    # three or four printed decimals give the ratios to about ±2e-3.
    monolithic = monolithic_eigenstructure(two_mass(0.1, 1e-3))
    W = monolithic.vectors
    assert np.linalg.norm(W, axis=0) == pytest.approx(np.ones(4))
    largest = W[np.argmax(np.abs(W), axis=0), np.arange(4)]
    assert largest.imag == pytest.approx(np.zeros(4), abs=1e-15) and np.all(largest.real > 0)
    assert W[1, 0] / W[0, 0] == pytest.approx((-0.011 + 0.099j) / (-0.097 + 0.990j), abs=2e-3)
    assert W[0, 2] / W[1, 2] == pytest.approx((0.0001 - 0.0995j) / (0.0312 + 0.9945j), abs=2e-3)


def test_higher_order_holds_perturb_less(two_mass):
    # D = 1 + O(z^{q+1}): at 4 ms the largest primary-pole shift is 0.22 (ZOH), 0.024 (FOH),
    # 0.0029 (SOH); assert the ordering with a factor 5 between successive orders.
    model = two_mass(0.1, 4e-3)
    monolithic = monolithic_eigenstructure(model)
    shifts = [np.max(np.abs(_cosim(model, q)[1].primary.poles - monolithic.poles)) for q in (0, 1, 2)]
    assert shifts[0] > 5 * shifts[1] > 25 * shifts[2]


def test_latent_roots(two_mass):
    # Damped, 1 ms. Every latent root of the Padé model is stable; those accepted after polishing
    # are roots of the exact characteristic equation (σ_min/σ_max of T(s) at round-off).
    model = two_mass(0.1, 1e-3)
    _, cosim = _cosim(model)
    hold = InterfaceModel(0, model.macro_step)
    T = cosimulated_stiffness(model)
    assert len(cosim.latent_pade) == 12  # 2N + 2 holds x 6 states - 2N primary
    assert cosim.latent_abscissa < 0 and np.all(cosim.latent.real < 0)
    assert cosim.latent_converged.any()
    for s in cosim.latent[cosim.latent_converged]:
        sv = np.linalg.svd(T(s, hold.D(s)), compute_uv=False)
        assert sv[-1] / sv[0] < 1e-10
