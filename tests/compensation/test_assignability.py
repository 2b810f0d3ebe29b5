"""L k = n (Eqs. 22, 27–28, 48) and the assignability test rank L = rank [L n] (Eq. 33, §4.3)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.architecture import Architecture, ArchitectureError, full_feedback, rank_one
from zencosim.compensation.eigenstructure.assignment import (
    RANK_RTOL,
    NotAssignableError,
    assess_assignability,
    assignment_system,
    design_compensator,
)
from zencosim.compensation.eigenstructure.interface import InterfaceModel
from zencosim.compensation.eigenstructure.modes import monolithic_eigenstructure

# The three systems of §4.3: undamped at 1 ms, damped at 1 and 4 ms.
SYSTEMS = [(0.0, 1e-3), (0.1, 1e-3), (0.1, 4e-3)]
ARCHITECTURES = {
    "full": (lambda m: full_feedback(m), (8, 8), (8, 12)),
    "without_x2_star": (lambda m: full_feedback(m, exchanged_motion=False), (7, 8), (8, 9)),
    # the runtime's architecture (docs/compensation.md): x2* and v2* fed back, not the acceleration of x2*
    "without_x2_star_acceleration": (lambda m: full_feedback(m, exchanged_acceleration=False), (8, 8), (8, 11)),
    "rank_one": (rank_one, (4, 5), (8, 6)),
}


def _system(model, architecture):
    hold = InterfaceModel(0, model.macro_step)
    return assignment_system(model, hold, architecture, monolithic_eigenstructure(model))


@pytest.mark.parametrize("damping, macro_step", SYSTEMS)
@pytest.mark.parametrize("name", ARCHITECTURES)
def test_ranks_of_section_4_3(two_mass, damping, macro_step, name):
    build, ranks, shape = ARCHITECTURES[name]
    model = two_mass(damping, macro_step)
    system = _system(model, build(model))
    assert system.L.shape == shape  # (2N p, 3 m r): p = 2 rows, 3 gains per feedback term
    report = assess_assignability(system)
    assert (report.rank_L, report.rank_Ln) == ranks
    assert report.assignable == (ranks[0] == ranks[1])
    # The decision is far from the tolerance: measured smallest counted singular value >= 0.25,
    # largest uncounted <= 3e-16 (column-scaled), against RANK_RTOL = 1e-8.
    for sv, rank in ((report.singular_values_L, report.rank_L), (report.singular_values_Ln, report.rank_Ln)):
        assert sv[rank - 1] > 1e-2 * sv[0]
        assert rank == len(sv) or sv[rank] < 1e-12 * sv[0]


def test_l_and_n_are_eqs_27_28(two_mass):
    model = two_mass(0.1, 4e-3)
    hold = InterfaceModel(0, model.macro_step)
    monolithic = monolithic_eigenstructure(model)
    system = assignment_system(model, hold, full_feedback(model), monolithic)
    assert system.rows == (0, 1)
    for i, (lam, w) in enumerate(zip(monolithic.poles, monolithic.vectors.T)):
        D, g_c = hold.D(lam), lam * 0.1 + 100.0
        w1, w2 = w
        block = np.array([[w1, w2 * D, 0, 0], [0, 0, w1 * D, w2]])
        expected_L = np.hstack([lam**2 * block, lam * block, block])  # [L_a, L_v, L_d]
        expected_n = -np.array([g_c * (1 - D) * w2, g_c * (1 - D) * w1 + g_c * (D**2 - 1) * w2])
        assert system.L[2 * i : 2 * i + 2] == pytest.approx(expected_L, rel=1e-13)
        assert system.n[2 * i : 2 * i + 2] == pytest.approx(expected_n, rel=1e-13)


def test_rank_one_compensation_is_eq_35(two_mass):
    model = two_mass(0.1, 1e-3)
    architecture = rank_one(model)
    d1, d2, f1, f2, g1, g2 = np.random.default_rng(3).standard_normal(6)
    BdG = architecture.stiffness(np.array([d1, d2, f1, f2, g1, g2]), model.n_dof)
    for s, D in ((3.0 + 10.0j, 0.9 - 0.1j), (-50.0 + 2.0j, 1.1 + 0.3j)):
        r1, r2 = s**2 * d1 + s * f1 + g1, s**2 * d2 + s * f2 + g2
        assert BdG(s, D) == pytest.approx(np.array([[r1, r2 * D], [-r1 * D, -r2 * D**2]]), rel=1e-13)


def test_four_mass_compensation_is_eq_48(four_mass):
    model = four_mass()
    architecture = full_feedback(model)
    assert architecture.n_gains == 21
    k = np.random.default_rng(4).standard_normal(21)
    s, D = 2.0 + 15.0j, 0.95 - 0.05j
    r = s**2 * k[:7] + s * k[7:14] + k[14:]  # r_1 .. r_7
    expected = np.zeros((4, 4), dtype=complex)
    expected[1] = [r[0], r[1], r[2] * D, 0]
    expected[2] = [r[3] * D, r[4] * D, r[5], r[6]]
    assert architecture.stiffness(k, 4)(s, D) == pytest.approx(expected, rel=1e-13)


def test_four_mass_architecture_is_assignable(four_mass):
    # §6.1: "this control architecture satisfies the assignability condition" — 16 = 16 with
    # L 16 x 21. Its 16th singular value is small (measured 3.3e-8, column-scaled), which the
    # design treats specially (see test_compensator_design).
    model = four_mass()
    report = assess_assignability(_system(model, full_feedback(model)))
    assert (report.rank_L, report.rank_Ln) == (16, 16)
    assert RANK_RTOL < report.singular_values_L[15] < 1e-6


@pytest.mark.parametrize("name", ["without_x2_star", "rank_one"])
def test_design_refuses_unassignable_architectures(two_mass, name):
    model = two_mass(0.1, 1e-3)
    with pytest.raises(NotAssignableError, match=r"expected rank L = rank \[L n\]") as error:
        design_compensator(model, InterfaceModel(0, model.macro_step), ARCHITECTURES[name][0](model))
    assert error.value.assignability.rank_L == ARCHITECTURES[name][1][0]


def test_gain_labels_follow_eq_24(two_mass):
    labels = full_feedback(two_mass(0.1, 1e-3)).gain_labels()
    assert labels == tuple(f"{kind}{i}" for kind in "dfg" for i in range(1, 5))


def test_architecture_errors(two_mass):
    model = two_mass(0.1, 1e-3)
    with pytest.raises(ArchitectureError, match="one force–displacement bond; the model has 2"):
        full_feedback(dataclasses.replace(model, bonds=model.bonds * 2))
    with pytest.raises(ArchitectureError, match="expects 12 gains"):
        full_feedback(model).stiffness(np.zeros(11), 2)
    bad = Architecture("bad", full_feedback(model).forces)
    with pytest.raises(ArchitectureError, match="expected 0..0"):
        bad.gain_directions(1)
