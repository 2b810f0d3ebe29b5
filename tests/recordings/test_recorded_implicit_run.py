"""A recorded rolled-back run (the implicit scheme of paper 003): its SAVE, RESTORE, STEP and PROJECT
commands, their replies and the per-step status are recorded, and re-running the recording's scene
gives every message bit for bit (the scheme's ACKs included)."""
from __future__ import annotations

import pytest

import zencosim
from zencosim.manager.scene.load import load_scene
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.reader import read_recording
from zencosim.recordings.verify import verify

pytestmark = pytest.mark.multiprocess


@pytest.mark.timeout(120)
def test_a_recorded_implicit_run_verifies_bit_for_bit(tmp_path):
    path = tmp_path / "implicit.mcap"
    scene = load_scene("constrained_two_mass", ["manager.duration=0.05", "manager.implicit.method=projection",
                                                "couplings.joint.decomposition=force-displacement"])
    zencosim.run(scene, record=path)
    recording = read_recording(path)
    kinds = {m.kind for m in recording.channels["S1/commands"].messages}
    assert {Kind.SAVE, Kind.RESTORE, Kind.STEP, Kind.PROJECT} <= kinds
    assert len(recording.channels["manager/status"].messages) == 50
    result = verify(recording)
    assert result.passed, (result.divergence, result.note)
