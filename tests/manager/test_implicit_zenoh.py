"""A rolled-back run over Zenoh: real subsystem processes on loopback execute every SAVE, RESTORE, STEP
and PROJECT of the implicit scheme (each process runs a replica of the scheme, manager.scheme.replica) and
give the same digest, trajectories, coupling variables and corrector runs as the in-process bus."""
from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import record_of
from zencosim.manager.results.summary import digest

pytestmark = pytest.mark.multiprocess


@pytest.mark.timeout(120)
@pytest.mark.parametrize("scene, overrides", [
    ("constrained_two_mass", ("manager.duration=0.2", "manager.implicit.method=projection",
                              "couplings.joint.decomposition=force-displacement", "manager.extrapolation=2")),
    ("double_pendulum", ("manager.duration=0.05", "manager.implicit.method=weighted-multiplier")),
], ids=["constrained_two_mass-projection", "double_pendulum-weighted-multiplier"])
def test_rolled_back_run_is_identical_over_zenoh(scene, overrides):
    inproc = record_of(scene, *overrides)
    zenoh = record_of(scene, *overrides, bus="zenoh")
    assert digest(zenoh) == digest(inproc)
    for a, b in zip(inproc.trajectories, zenoh.trajectories):
        assert a.tobytes() == b.tobytes()
    assert np.array_equal(inproc.implicit.coupling_variables, zenoh.implicit.coupling_variables)
    assert np.array_equal(inproc.implicit.corrector_runs, zenoh.implicit.corrector_runs)

