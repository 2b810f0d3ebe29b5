"""Paper 002's planar and multiphysics benchmarks, with energy correction, in one process and over Zenoh
(real subsystem processes on loopback): bit-identical outputs, residuals and correction forces."""
from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import record_of

pytestmark = pytest.mark.multiprocess


@pytest.mark.timeout(180)
@pytest.mark.parametrize("scene,duration", [("coupled_pendula", "1.0"), ("hydraulic_crane", "0.5")])
def test_corrected_run_is_identical_in_process_and_over_zenoh(scene, duration):
    overrides = (f"manager.duration={duration}", "manager.correction.enabled=true")
    inproc = record_of(scene, *overrides)
    zenoh = record_of(scene, *overrides, bus="zenoh")
    for a, b in zip(inproc.trajectories, zenoh.trajectories):
        assert a.tobytes() == b.tobytes()
    assert np.array_equal(inproc.residual_energy, zenoh.residual_energy, equal_nan=True)
    (log_a,), (log_b,) = inproc.corrections, zenoh.corrections
    assert log_a.force.tobytes() == log_b.force.tobytes() and np.any(log_a.force != 0.0)
