"""Explicit Jacobi co-simulation of the papers' linear benchmarks: what is stable, what gains energy,
and the residual power that accounts for it."""
from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import record_of, summary_of
from zencosim.manager.results.summary import total_energy

FOUR_MS = ["manager.macro_step=0.004", "subsystems.S1.micro_step=0.004", "subsystems.S2.micro_step=0.004"]


def test_damped_two_mass_at_1ms_stays_bounded():
    summary = summary_of("two_mass_damped")
    assert summary["stable"]
    assert summary["energy"]["final"] < 0.5 * summary["energy"]["initial"]  # dissipation wins: 2474 J of 10000 J


def _growth(record) -> tuple[float, float]:
    """Energy growth rate [1/s] fitted on the windowed maxima of each half of the run."""
    t, energy = total_energy(record)
    half = len(t) // 2
    rates = []
    for part in (slice(0, half), slice(half, None)):
        windows = np.array_split(np.arange(len(t))[part], 10)
        peaks = [energy[w].max() for w in windows]
        rates.append(np.polyfit([t[w].mean() for w in windows], np.log(peaks), 1)[0])
    return rates[0], rates[1]


@pytest.mark.slow
@pytest.mark.parametrize("scene,overrides", [("two_mass_undamped", []), ("two_mass_damped", FOUR_MS)],
                         ids=["undamped_1ms", "damped_4ms"])
def test_unstable_cases_of_paper_000_gain_energy_without_bound(scene, overrides):
    # paper 000 Tables 1-2: a co-simulated pole pair in the right half plane. Over 60 s the energy must
    # grow exponentially at the same rate in both halves of the run (no saturation), by orders of magnitude.
    record = record_of(scene, "manager.duration=60", *overrides)
    first, second = _growth(record)
    _, energy = total_energy(record)
    assert first > 0.05 and second > 0.05  # we measure 0.098 (undamped 1 ms) and 0.18 (damped 4 ms) 1/s
    assert second == pytest.approx(first, rel=0.3)
    assert energy[-1] > 100 * energy[0]


def test_residual_energy_accounts_for_half_the_energy_error_single_rate():
    # paper 002 §3.3: with one subsystem with direct feedthrough, single rate, zeta = mu * dE with mu = 0.5;
    # the double oscillator case 1 has no dissipation, so zeta = E(T) - E(0)
    summary = summary_of("double_oscillator")
    zeta = summary["energy"]["final"] - summary["energy"]["initial"]
    assert zeta / summary["residual_energy"]["c"] == pytest.approx(0.5, abs=0.05)  # we measure 0.475


def test_multirate_double_oscillator_completes_and_is_bounded():
    # h1 = 1 ms for M1 (direct feedthrough), h2 = 0.1 ms for M2: base step 0.1 ms, ratio R = 10
    record = record_of("double_oscillator", "manager.macro_step=0.0001", "subsystems.M1.comm_ratio=10",
                       "subsystems.M2.micro_step=0.0001")
    m1, m2 = record.trajectories
    assert m1.shape[0] == 10_001 and m2.shape[0] == 100_001  # each subsystem at its own communication points
    assert np.isfinite(m1).all() and np.isfinite(m2).all()
    _, energy = total_energy(record)
    assert energy.max() < 5 * energy[0]  # case 1 is undamped and gains energy, but only 3x over 10 s
    # the residual energy is only evaluated where both sides communicate, every 1 ms
    assert np.isfinite(record.residual_power[::10, 0]).all() and np.isnan(record.residual_power[1:10, 0]).all()
    # paper 002 Eq. 20 (feedthrough side has the larger step, ZOH): mu = 0.5 (1.5 - 0.5 / 10) = 0.725; we measure 0.69
    ratio = (energy[-1] - energy[0]) / record.residual_energy[-1, 0]
    assert ratio == pytest.approx(0.725, abs=0.07)


def test_extrapolation_order_changes_the_result_and_foh_is_more_accurate_here():
    zoh, foh = (summary_of("two_mass_damped", f"manager.extrapolation={p}") for p in (0, 1))
    assert foh["digest"] != zoh["digest"]
    assert foh["signals"]["x2"]["nrms"] < zoh["signals"]["x2"]["nrms"]


def test_the_same_scene_gives_the_same_digest_twice():
    assert summary_of("four_mass")["digest"] == summary_of("four_mass")["digest"]
