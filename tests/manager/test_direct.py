"""The in-process fast path (``manager.bus.inproc.DirectCalls``): the scheme calling the subsystems itself, with arrays,
computes every value that the run through the wire protocol computes, bit for bit — the one digest of both buses
stays one — and names a failing model as its ERROR reply would.

The oracle is the general path on the same scene (commands and replies encoded, decoded and checked, as over
Zenoh), whose equality with a Zenoh run tests/manager/test_buses.py checks."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import zencosim.examples
from tests.manager.frames_recorder import FramesRecorder
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.results.summary import digest
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.scheme.jacobi import schedule
from zencosim.manager.scheme.replica import PerMessage
from zencosim.manager.scheme import tapped
from zencosim.manager.scheme.tapped import Taken, TakenSteps, taken_for
from zencosim.manager.wire.protocol import HEADER
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.recorder_process import BATCH, ROWS, frame_messages
from zencosim.recordings.recorder_process import STEPS as STEPS_FRAME
from zencosim.recordings.rows_frame import END_STATUS, ROWS_HEAD, STATUS
from zencosim.recordings.steps_frame import STEPS_HEAD, pending_steps
from zencosim.scenes import __path__ as bundled

EXAMPLES = Path(zencosim.examples.__file__).parent / "scenes"
SCENES = sorted(p.stem for p in Path(bundled[0]).glob("*.toml"))
VARIANTS = {  # the schemes' branches: extrapolation orders, multi-rate, energy correction, the compensator
    "two_mass_damped_soh": ("two_mass_damped", ["manager.extrapolation=2"]),
    "double_oscillator_multi_rate_foh": ("double_oscillator", ["manager.macro_step=0.0001", "subsystems.M1.comm_ratio=10",
                                                               "subsystems.M2.micro_step=0.0001",
                                                               "manager.extrapolation=1"]),
    "double_oscillator_corrected": ("double_oscillator", ["manager.correction.enabled=true"]),
    "hydraulic_crane_corrected": ("hydraulic_crane", ["manager.correction.enabled=true"]),
    "four_mass_compensated": ("four_mass", ["manager.compensation=eigenstructure"]),
    "four_mass_gauss_seidel_soh": ("four_mass", ["manager.scheme=gauss-seidel", "manager.extrapolation=2"]),
    "mass_chain_gauss_seidel_order": ("mass_chain", ["manager.scheme=gauss-seidel"]),
    "double_oscillator_multi_rate_gauss_seidel": ("double_oscillator", [
        "manager.macro_step=0.0001", "subsystems.M1.comm_ratio=10", "subsystems.M2.micro_step=0.0001",
        "manager.scheme=gauss-seidel", 'manager.order=["M1", "M2"]', "manager.extrapolation=1"]),
    "python_model": (str(EXAMPLES / "two_mass_damped_python.toml"), []),
    "dc_motor": (str(EXAMPLES / "dc_motor_drive.toml"), []),
}
STEPS = 300  # base macro-steps of each run (rounded up to the schedule's period)


def _two_runs(name: str, overrides: list[str]):
    """The same scene run through the wire protocol and directly: (record through messages, direct record)."""
    records = []
    for direct in (False, True):
        scene = load_scene(name, overrides)
        plan, _ = plan_scene(scene)
        period = math.lcm(*(s.ratio for s in plan.subsystems))
        ticks = -(-STEPS // period) * period
        scene = load_scene(name, [*overrides, f"manager.duration={ticks * scene.manager.macro_step_ns / 1e9!r}"])
        plan, subsystems = plan_scene(scene)
        scheme = make_scheme(scene, plan, direct=DirectCalls(plan, subsystems) if direct else None)
        with np.errstate(over="ignore", invalid="ignore"):
            records.append(run_in_process(scheme, plan, subsystems))
    return records


@pytest.mark.parametrize("name, overrides", [*((name, []) for name in SCENES), *VARIANTS.values()],
                         ids=[*SCENES, *VARIANTS])
def test_the_direct_path_computes_every_value_of_the_message_path(name, overrides):
    through_messages, direct = _two_runs(name, overrides)
    assert digest(direct) == digest(through_messages)
    for ours, theirs in zip(direct.trajectories, through_messages.trajectories):
        assert np.array_equal(ours, theirs, equal_nan=True)
    assert np.array_equal(direct.residual_power, through_messages.residual_power, equal_nan=True)
    assert np.array_equal(direct.residual_energy, through_messages.residual_energy, equal_nan=True)
    assert len(direct.corrections) == len(through_messages.corrections)
    for ours, theirs in zip(direct.corrections, through_messages.corrections):
        assert np.array_equal(np.asarray(ours.work), np.asarray(theirs.work), equal_nan=True)
    if direct.implicit is not None:  # the implicit scheme exchanges messages either way
        assert np.array_equal(direct.implicit.coupling_variables, through_messages.implicit.coupling_variables)


def test_a_failing_model_is_named_as_its_error_reply_names_it(tmp_path, monkeypatch):
    """A model raising in its step: the same one line on both paths (the subsystem, the step, the exception), and a
    recording of each holds the same messages, up to the failing step's commands."""
    (tmp_path / "failing_model.py").write_text(
        "from zencosim.examples.oscillator import Oscillator\n"
        "class Failing(Oscillator):\n"
        "    def acceleration(self, t, z, u):\n"
        "        if t >= 0.05:\n"
        "            raise ValueError('table lookup out of range')\n"
        "        return super().acceleration(t, z, u)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    text = (EXAMPLES / "two_mass_damped_python.toml").read_text()
    head, _, tail = text.partition("[subsystems.S2]")
    scene_file = tmp_path / "failing.toml"
    scene_file.write_text(head + "[subsystems.S2]" + tail.replace("zencosim.examples.oscillator:Oscillator",
                                                                  "failing_model:Failing", 1))
    said, recorded = [], []
    for direct in (False, True):
        scene = load_scene(str(scene_file), ["manager.duration=0.2"])
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        recorder = FramesRecorder(plan, status)  # what the recording holds: every message up to the failure
        with pytest.raises(SubsystemFailure) as failure:
            run_in_process(make_scheme(scene, plan, status=status,
                                       direct=DirectCalls(plan, subsystems) if direct else None, tap=recorder),
                           plan, subsystems, recorder)
        recorder.flush(last=True)
        said.append(str(failure.value))
        recorded.append(recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)))
    assert said[0] == said[1] and said[1].startswith("subsystem S2: failed at step ")
    assert len(recorded[1]) > 200 and recorded[0] == recorded[1]
    assert said[1].endswith(": ValueError: table lookup out of range"), said


@pytest.mark.parametrize("name, overrides", [VARIANTS["two_mass_damped_soh"], VARIANTS["double_oscillator_multi_rate_foh"],
                                             VARIANTS["double_oscillator_corrected"],
                                             VARIANTS["four_mass_gauss_seidel_soh"],
                                             VARIANTS["double_oscillator_multi_rate_gauss_seidel"],
                                             ("hydraulic_crane", [])],
                         ids=["soh", "multi-rate", "corrected", "gauss-seidel", "multi-rate-gauss-seidel",
                              "hydraulic_crane"])
def test_a_tap_sees_the_same_messages_in_the_same_order_on_both_paths(name, overrides):
    """A recorded run takes the direct path too: the scheme encodes the commands and replies and hands them to the
    tap as a replica would — every message, byte for byte and in order, the status's residuals included (its wall
    times are each run's own; a recording of either path verifies against the other: tests/recordings)."""
    seen = []
    for direct in (False, True):
        scene = load_scene(name, [*overrides, "manager.duration=0.12"])
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        messages = []
        residuals_end = HEADER.size + 8 * 2 * len(plan.bonds)  # a status message's header, δP and δE of every bond

        def keep(source: str, channel: str, message: bytes) -> None:
            messages.append((source, channel, bytes(message[:residuals_end] if channel == "status" else message)))
        tap = PerMessage(keep, status)
        scheme = make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems) if direct else None,
                             tap=tap)
        run_in_process(scheme, plan, subsystems, tap)
        seen.append(messages)
    assert len(seen[1]) > 100 and seen[0] == seen[1]


@pytest.mark.parametrize("name, overrides, duration", [("two_mass_damped", [], 1.2),
                                                       (*VARIANTS["double_oscillator_multi_rate_foh"], 0.12),
                                                       (*VARIANTS["double_oscillator_multi_rate_gauss_seidel"], 0.12),
                                                       (*VARIANTS["mass_chain_gauss_seidel_order"], 0.3),
                                                       ("hydraulic_crane", [], 0.5)],
                         ids=["two_mass_damped", "multi-rate", "multi-rate-gauss-seidel", "gauss-seidel-chain",
                              "hydraulic_crane"])
def test_the_recorder_takes_the_messages_of_the_message_path_from_blocks_of_arrays(name, overrides, duration):
    """A recorded direct run hands the recorder blocks of arrays (manager.scheme.tapped: TakenSteps, STEPS frames;
    a generated loop's TakenRows, ROWS frames); the messages the recorder process builds from them
    (recordings.steps_frame, rows_frame) are those a replica's tap hands it
    exchange by exchange on the message path: every message, byte for byte, in order and with its channel index —
    the statuses included, but for the wall times in them (each run's own)."""
    seen = []
    for direct in (False, True):
        scene = load_scene(name, [*overrides, f"manager.duration={duration}"])
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        recorder = FramesRecorder(plan, status)
        scheme = make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems) if direct else None,
                             tap=recorder)
        run_in_process(scheme, plan, subsystems, recorder)
        recorder.flush(last=True)
        kinds = {kind for kind, _ in recorder.frames}
        # the initialisation, then blocks: a generated loop's rows (manager.scheme.compiled), else the scheme's arrays
        blocks = ROWS if name == "two_mass_damped" else STEPS_FRAME
        assert kinds == ({BATCH, blocks} if direct else {BATCH}), kinds
        seen.append(recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)))  # a status: header, δP, δE
        if direct:
            assert recorder.published == {topic: sum(1 for i, _ in seen[1] if recorder._topics[i] == topic)
                                          for topic in recorder._topics}
    assert len(seen[1]) > 500 and seen[0] == seen[1]


@pytest.mark.parametrize("name, overrides, duration", [(*VARIANTS["python_model"], 0.6),
                                                       (*VARIANTS["double_oscillator_multi_rate_foh"], 0.12),
                                                       (*VARIANTS["double_oscillator_multi_rate_gauss_seidel"], 0.12)],
                         ids=["python_model", "multi-rate", "multi-rate-gauss-seidel"])
def test_a_run_that_ends_after_any_pending_frame_leaves_every_message_up_to_it(name, overrides, duration,
                                                                                 monkeypatch):
    """The scheme's loop hands the recorder process what it holds as PENDING frames between its blocks (every
    handover_size requests here: no time to wait, FIRST_HANDOVER_NS = HANDOVER_COSTS = 0), and a recorder process
    whose run's process ended records the block it builds from those since the last block
    (recordings.steps_frame.pending_steps). Whichever
    PENDING frame is the last, what it then holds is the run's messages up to there: a prefix of every message the
    run hands over, byte for byte (a status's wall times aside), that grows with each PENDING frame."""
    monkeypatch.setattr(tapped, "FIRST_HANDOVER_NS", 0)
    monkeypatch.setattr(tapped, "HANDOVER_COSTS", 0)
    scene = load_scene(name, [*overrides, f"manager.duration={duration}"])
    plan, subsystems = plan_scene(scene)
    status = StatusReport(plan, False)
    recorder = FramesRecorder(plan, status)
    run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems), tap=recorder), plan,
                   subsystems, recorder)
    recorder.flush(last=True)
    residuals_end = HEADER.size + 8 * 2 * len(plan.bonds)
    whole = recorder.messages(residuals_end)
    assert len(recorder.pending) > 2 * len([kind for kind, _ in recorder.frames if kind == STEPS_FRAME])
    kept = 0
    for k, (before, _) in enumerate(recorder.pending):
        since = [payload for frames, payload in recorder.pending[:k + 1] if frames == before]
        held = (recorder.frames_messages(recorder.frames[:before], residuals_end)
                + recorder.frames_messages([(STEPS_FRAME, pending_steps(since))], residuals_end))
        assert held == whole[:len(held)] and len(held) > kept, k
        kept = len(held)


def test_a_long_schedule_period_or_a_paced_run_is_tapped_exchange_by_exchange():
    """A block holds whole schedule periods: M1 at 4,099 base steps (a period longer than LONGEST_PERIOD) would hold
    them all in memory, and a real-time run's live view follows it step by step; both are handed to the recorder
    exchange by exchange (BATCH frames only), still the message path's messages."""
    long_period = ["manager.macro_step=0.000001", "subsystems.M1.comm_ratio=4099", "subsystems.M1.micro_step=0.004099",
                   "subsystems.M2.micro_step=0.000001", "manager.duration=0.008198"]
    plan, _ = plan_scene(load_scene("double_oscillator", long_period))
    recorder = FramesRecorder(plan, StatusReport(plan, False))
    crane = plan_scene(load_scene("hydraulic_crane"))[0]

    def taken(plan, paced):
        every = frozenset(range(len(plan.subsystems)))
        return taken_for(recorder, plan, paced, True, schedule(plan, every, every)[1])
    assert isinstance(taken(plan, False), Taken)
    assert isinstance(taken(crane, True), Taken)
    assert isinstance(taken(crane, False), TakenSteps)
    seen = []
    for direct in (False, True):
        scene = load_scene("double_oscillator", long_period)
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        recorder = FramesRecorder(plan, status)
        run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems) if direct else None,
                                   tap=recorder), plan, subsystems, recorder)
        recorder.flush(last=True)
        assert {kind for kind, _ in recorder.frames} == {BATCH}
        seen.append(recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)))
    assert len(seen[1]) > 8000 and seen[0] == seen[1]


def _block_frame(name: str, kind: int) -> tuple[FramesRecorder, bytes]:
    """The recorder of a short recorded direct run of scene ``name`` and its first frame of ``kind``."""
    scene = load_scene(name, ["manager.duration=0.2"])
    plan, subsystems = plan_scene(scene)
    status = StatusReport(plan, False)
    recorder = FramesRecorder(plan, status)
    run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems), tap=recorder),
                   plan, subsystems, recorder)
    return recorder, next(data for found, data in recorder.frames if found == kind)


def test_a_steps_frame_that_does_not_hold_what_its_head_says_is_refused():
    """Cut short, lengthened, or with a layout number past its layouts: a ValueError naming the frame, as a BATCH
    frame's (recorder_process.split_batch), never wrong messages."""
    recorder, frame = _block_frame("hydraulic_crane", STEPS_FRAME)
    frame_messages(STEPS_FRAME, frame, recorder._index, recorder._status)  # whole: read
    text_bytes, m, statuses_bytes, _ = STEPS_HEAD.unpack_from(frame)
    order_at = STEPS_HEAD.size + text_bytes + 8 * m + statuses_bytes
    wrong_layout = frame[:order_at] + (10**6).to_bytes(4, "little") + frame[order_at + 4:]
    for damaged in (frame[:-8], frame + b"\0" * 8, frame[:STEPS_HEAD.size + 3], wrong_layout):
        with pytest.raises(ValueError, match="a STEPS frame that does not hold what its head says"):
            frame_messages(STEPS_FRAME, damaged, recorder._index, recorder._status)


def test_a_rows_frame_that_does_not_hold_what_its_head_says_is_refused():
    """Cut short, lengthened, more requests than rows, replies said to follow a request past the rows, the run's last
    status without its replies: a ValueError naming the frame, never wrong messages."""
    recorder, frame = _block_frame("two_mass_damped", ROWS)
    frame_messages(ROWS, frame, recorder._index, recorder._status)  # whole: read
    head = list(ROWS_HEAD.unpack_from(frame))

    def with_head(**changes: int) -> bytes:
        fields = dict(zip(("about", "rows", "requests", "flags"), head[:4]), **changes)
        return ROWS_HEAD.pack(*fields.values(), *head[4:]) + frame[ROWS_HEAD.size:]
    for damaged in (frame[:-8], frame + b"\0" * 8, frame[:ROWS_HEAD.size + 3], with_head(requests=head[1] + 1),
                    with_head(requests=head[1]), with_head(requests=0), with_head(flags=END_STATUS | STATUS)):
        with pytest.raises(ValueError, match="a ROWS frame that does not hold what its head says"):
            frame_messages(ROWS, damaged, recorder._index, recorder._status)
