"""Recordings of in-process runs: what the file holds, that standard tooling reads it, that verification
catches a difference, that a killed recorder leaves a readable file, and that bad input is named.

The recorder is a real process fed by the in-process bus's tap.
"""
from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

import zencosim
from tests.conftest import REPO, children_of, cmdline
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import run_in_process
from zencosim.manager.scene.load import load_scene, scene_from_text
from zencosim.manager.wire.protocol import Kind
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.layout import SCENE_ATTACHMENT
from zencosim.recordings.reader import read_recording
from zencosim.recordings.recorder import Recorder
from zencosim.recordings.recorder_process import IDLE_S
from zencosim.recordings.verify import verify
from zencosim.recordings.writer import FLUSH_INTERVAL_S, RecordingWriter

pytestmark = pytest.mark.multiprocess

SCENE = ("two_mass_damped", ["manager.duration=2.0"])  # 2000 macro-steps


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """An in-process run of 2000 steps, recorded: (file, run record, recorder's end record, wall clock [ns]
    before and after the run)."""
    path = tmp_path_factory.mktemp("recorded") / "run.mcap"
    before = time.time_ns()
    result = zencosim.run(zencosim.load_scene(*SCENE), record=path)
    return path, result.record, result.summary["recording"], (before, time.time_ns())


def test_the_file_holds_every_message_bit_for_bit(recorded):
    path, record, result, _ = recorded
    plan = record.plan
    assert result["outcome"] == "completed" and result["lost"] == 0 and result["malformed"] == 0
    assert all(c["published"] == c["received"] == (plan.n_ticks if t == "manager/status" else plan.n_ticks + 1)
               for t, c in result["channels"].items())
    recording = read_recording(path)
    assert recording.truncated is None and recording.end["lost"] == 0
    for sub in plan.subsystems:
        steps, times, outputs = recording.channels[f"{sub.name}/y"].table(Kind.OUTPUT)
        assert steps.tolist() == list(range(plan.n_ticks + 1))
        assert times.tolist() == (steps * plan.base_step_ns).tolist()
        assert outputs.tobytes() == record.trajectories[sub.index].tobytes()
        received = [m for m in recording.channels[f"{sub.name}/commands"].messages if m.kind == Kind.STEP]
        assert [m.step for m in received] == list(range(plan.n_ticks))
    # ZOH: what S1 received at step j is what S2 reported at step j (x2, v2)
    s1_inputs = np.array([m.values for m in recording.channels["S1/commands"].messages if m.kind == Kind.STEP])
    assert s1_inputs.tobytes() == record.trajectories[1][:-1, :2].tobytes()
    steps, _, status = recording.channels["manager/status"].table(Kind.STATUS)
    names = recording.channels["manager/status"].spec.names
    assert steps.tolist() == list(range(1, plan.n_ticks + 1))
    assert status[:, names.index("delta_p.c")].tobytes() == record.residual_power[1:, 0].tobytes()
    assert status[:, names.index("delta_e.c")].tobytes() == record.residual_energy[1:, 0].tobytes()
    assert np.all(np.diff(status[:, names.index("wall_time")]) >= 0)


def test_the_file_says_what_ran_and_holds_a_scene_that_reruns_it(recorded):
    path, _, _, _ = recorded
    recording = read_recording(path)
    info = recording.info
    assert (info["scene"], info["bus"], info["steps"], info["macro_step_ns"]) == ("two_mass_damped", "inproc",
                                                                                  "2000", "1000000")
    assert info["run_id"] and info["zencosim"] and info["overrides"] == '["manager.duration=2.0"]'
    assert info["scene_file"] == "two_mass_damped.toml"
    # shared as it is: no host name and no absolute path, unless asked (--record-host-info)
    assert "host" not in info and "scene_source" not in info and recording.end["path"] == "run.mcap"
    assert not any(socket.gethostname() in value or str(REPO) in value or str(path.parent) in value
                   for record in (info, recording.end) for value in map(str, record.values()))
    scene = scene_from_text(recording.scene_toml, SCENE_ATTACHMENT)
    assert scene.digest == info["scene_digest"] == load_scene(*SCENE).digest


def _decoded(path) -> dict[str, list]:
    """Every message of every channel, decoded by the mcap library's protobuf decoder: topic → (log time, message)."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    found: dict[str, list] = {}
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        for _, channel, message, proto in reader.iter_decoded_messages(log_time_order=False):
            found.setdefault(channel.topic, []).append((message.log_time, proto))
    return found


def test_standard_mcap_tooling_reads_every_signal_by_its_name_bit_for_bit(recorded):
    path, record, result, (before, after) = recorded
    decoded = _decoded(path)
    assert sum(map(len, decoded.values())) == result["messages"]
    plan = record.plan
    for sub in plan.subsystems:
        outputs = [proto for _, proto in decoded[f"{sub.name}/y"] if proto.kind == Kind.OUTPUT]
        assert [f.name for f in outputs[0].DESCRIPTOR.fields][8:] == [p.name for p in sub.outputs]
        for j, port in enumerate(sub.outputs):  # S2's x2, v2, energy; S1's fc, energy: each a double field
            column = np.array([getattr(proto, port.name) for proto in outputs])
            assert column.tobytes() == record.trajectories[sub.index][:, j].tobytes(), port.name
        assert [proto.step for proto in outputs] == list(range(plan.n_ticks + 1))
        assert [proto.sim_time for proto in outputs] == [proto.time_ns * 1e-9 for proto in outputs]
        assert [proto.time_ns for proto in outputs] == [k * plan.base_step_ns for k in range(plan.n_ticks + 1)]
    # what S1 received at step j (ZOH: a constant) is what S2 reported at step j: x2* arrives as field x2
    steps = [proto for _, proto in decoded["S1/commands"] if proto.kind == Kind.STEP]
    assert np.array([list(proto.x2) + list(proto.v2) for proto in steps]).tobytes() == \
        record.trajectories[1][:-1, :2].tobytes()
    status = [proto for _, proto in decoded["manager/status"]]
    assert np.array([proto.delta_p.c for proto in status]).tobytes() == record.residual_power[1:, 0].tobytes()
    assert np.array([proto.delta_e.c for proto in status]).tobytes() == record.residual_energy[1:, 0].tobytes()
    # the log time is the wall clock when the step was handed to the recorder: within the run
    log_times = [t for messages in decoded.values() for t, _ in messages]
    assert before <= min(log_times) <= max(log_times) <= after


def test_verification_passes_then_names_the_first_difference(recorded):
    path, _, _, _ = recorded
    assert verify(read_recording(path)).passed

    recording = read_recording(path)
    channel = recording.channels["S2/y"]
    original = channel.messages[700]
    flipped = original.values.copy()
    flipped.view(np.uint64)[0] ^= 1  # one bit of x2 at step 700
    channel.messages[700] = dataclasses.replace(original, values=flipped)
    result = verify(recording)
    assert not result.passed
    assert (result.divergence.channel, result.divergence.step, result.divergence.what) == ("S2/y", 700, "x2")
    assert result.divergence.recorded != result.divergence.rerun
    assert f"{flipped[0]!r}" in result.divergence.recorded and f"{original.values[0]!r}" in result.divergence.rerun

    recording = read_recording(path)
    del recording.channels["S1/y"].messages[300]  # a lost message
    result = verify(recording)
    assert (result.divergence.channel, result.divergence.step, result.divergence.what) == ("S1/y", 300, "step")
    assert result.divergence.recorded == "301"


@contextlib.contextmanager
def _recording_half_a_second(path, run_id: str):
    """A recorder of ``path`` that has been fed half a second of two_mass_damped in process, and the run's record;
    the recorder is closed after the block."""
    scene = load_scene("two_mass_damped", ["manager.duration=0.5"])
    plan, subsystems = plan_scene(scene)
    status = StatusReport(plan, realtime=False)
    recorder = Recorder(path)
    try:
        recorder.start(scene, plan, status, "inproc", run_id, realtime=False)
        yield recorder, run_in_process(make_scheme(scene, plan, status=status), plan, subsystems, recorder)
    finally:
        recorder.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux scheduling priorities")
def test_the_recorder_runs_at_idle_priority_and_still_records_every_message(tmp_path):
    """The recorder takes the CPU time the run leaves (SCHED_IDLE), in one thread (numpy's OpenBLAS starts no
    worker to spin beside the run), and backpressure keeps every message."""
    with _recording_half_a_second(tmp_path / "idle.mcap", "idle") as (recorder, record):
        (pid,) = recorder.pids  # SCHED_IDLE; where the system refuses it, nice 19 (recordings.recorder)
        assert os.sched_getscheduler(pid) == os.SCHED_IDLE or os.getpriority(os.PRIO_PROCESS, pid) == 19
        assert os.listdir(f"/proc/{pid}/task") == [str(pid)]
        end = recorder.finish("completed")
    assert end["lost"] == 0 and end["messages"] == sum(recorder.published.values())
    _, _, outputs = read_recording(tmp_path / "idle.mcap").channels["S2/y"].table(Kind.OUTPUT)
    assert outputs.tobytes() == record.trajectories[1].tobytes()


def test_a_killed_recorder_leaves_every_message_it_had_for_half_a_second(tmp_path):
    path = tmp_path / "killed.mcap"
    with _recording_half_a_second(path, "killed") as (recorder, record):
        recorder.flush()
        time.sleep(FLUSH_INTERVAL_S + 2 * IDLE_S + 0.5)  # the idle recorder writes its open chunk out
        recorder_pid = next(pid for pid in children_of(os.getpid()) if "zencosim.recordings.recorder_process" in cmdline(pid))
        os.kill(recorder_pid, signal.SIGKILL)
    recording = read_recording(path)
    assert recording.truncated is not None and recording.end is None  # no footer, no end record
    assert {t: len(c.messages) for t, c in recording.channels.items()} == dict(recorder.published)
    _, _, outputs = recording.channels["S2/y"].table(Kind.OUTPUT)
    assert outputs.tobytes() == record.trajectories[1].tobytes()


def _zencosim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, cwd=REPO,
                          timeout=120)


def test_bad_input_gives_an_error_naming_the_file(recorded, tmp_path):
    not_mcap = tmp_path / "notes.mcap"
    not_mcap.write_text("hello\n")
    for command in (("inspect", str(not_mcap)), ("replay", str(not_mcap), "--verify")):
        result = _zencosim(*command)
        assert result.returncode == 2 and f"{not_mcap} is not an MCAP file" in result.stderr, result.stderr
    missing = tmp_path / "missing.mcap"
    result = _zencosim("inspect", str(missing))
    assert result.returncode == 2 and f"cannot read recording {missing}" in result.stderr

    # a recording made by a zencosim whose model "masses" this one no longer has
    path, _, _, _ = recorded
    good = read_recording(path)
    stale = tmp_path / "stale.mcap"
    writer = RecordingWriter(stale, good.info, good.scene_toml.replace('model = "masses"', 'model = "point_masses"'),
                             [c.spec for c in good.channels.values()])
    writer.finish("completed", {})
    result = _zencosim("replay", str(stale), "--verify")
    assert result.returncode == 2
    assert f"{stale}: its scene no longer loads" in result.stderr and "point_masses" in result.stderr, result.stderr

    result = _zencosim("replay", str(path))
    assert result.returncode == 2 and "nothing to do" in result.stderr


def test_inspect_shows_channels_counts_and_losses(recorded):
    path, _, _, _ = recorded
    result = _zencosim("inspect", str(path))
    assert result.returncode == 0, result.stderr
    for text in ("two_mass_damped", "S1/commands", "S2/y", "manager/status", "2001", "2000 of 2000", "2 s simulated",
                 "lost: 0", "completed"):
        assert text in result.stdout, text
    assert "host" not in result.stdout


def test_the_host_and_scene_path_are_recorded_when_asked(tmp_path):
    path = tmp_path / "hosted.mcap"
    result = _zencosim("run", "two_mass_damped", "--set", "manager.duration=0.01", "--quiet", "--record", str(path),
                       "--record-host-info")
    assert result.returncode == 0, result.stderr
    info = read_recording(path).info
    assert info["host"] == socket.gethostname() and info["scene_source"] == str(load_scene(*SCENE).path)


def _format_1_message_class():
    """The one generic ``zencosim.Message`` of format 1 recordings, built with the protobuf runtime."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    F = descriptor_pb2.FieldDescriptorProto
    file = descriptor_pb2.FileDescriptorProto(name="zencosim/message.proto", package="zencosim", syntax="proto3")
    message = file.message_type.add(name="Message")
    for name, number, kind, label in (("step", 1, F.TYPE_SFIXED64, F.LABEL_OPTIONAL),
                                      ("time_ns", 2, F.TYPE_SFIXED64, F.LABEL_OPTIONAL),
                                      ("kind", 3, F.TYPE_FIXED32, F.LABEL_OPTIONAL),
                                      ("rows", 4, F.TYPE_FIXED32, F.LABEL_OPTIONAL),
                                      ("values", 5, F.TYPE_DOUBLE, F.LABEL_REPEATED),
                                      ("text", 6, F.TYPE_STRING, F.LABEL_OPTIONAL),
                                      ("ref", 7, F.TYPE_FIXED32, F.LABEL_OPTIONAL)):
        message.field.add(name=name, number=number, type=kind, label=label)
    pool = descriptor_pool.DescriptorPool()
    pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName("zencosim.Message")), \
        descriptor_pb2.FileDescriptorSet(file=[file]).SerializeToString()


def test_a_format_1_recording_is_still_read_and_verified(recorded, tmp_path):
    from mcap.writer import Writer
    path, _, _, _ = recorded
    recording = read_recording(path)
    message_class, schema = _format_1_message_class()
    old = tmp_path / "format1.mcap"
    with open(old, "wb") as handle:  # as format 1 wrote it: one generic message, log time = simulated time
        writer = Writer(handle)
        writer.start()
        schema_id = writer.register_schema("zencosim.Message", "protobuf", schema)
        for topic, channel in recording.channels.items():
            channel_id = writer.register_channel(topic, "protobuf", schema_id, channel.spec.metadata())
            for m in channel.messages:
                data = message_class(step=m.step, time_ns=m.time_ns, kind=m.kind, rows=m.rows, values=m.values.tolist(),
                                     text=m.text, ref=m.ref).SerializeToString()
                writer.add_message(channel_id, max(m.time_ns, 0), data, 0)
        writer.add_metadata("zencosim", {**recording.info, "format": "zencosim-recording/1"})
        writer.add_attachment(0, 0, SCENE_ATTACHMENT, "application/toml", recording.scene_toml.encode())
        writer.finish()
    again = read_recording(old)
    for topic, channel in recording.channels.items():
        assert [(m.step, m.kind, m.values.tobytes()) for m in again.channels[topic].messages] == \
            [(m.step, m.kind, m.values.tobytes()) for m in channel.messages], topic
    assert verify(again).divergence is None

    newer = tmp_path / "format9.mcap"
    RecordingWriter(newer, {**recording.info, "format": "zencosim-recording/9"}, recording.scene_toml,
                    [c.spec for c in recording.channels.values()]).finish("completed", {})
    result = _zencosim("inspect", str(newer))
    assert result.returncode == 2 and "recording format 'zencosim-recording/9'" in result.stderr, result.stderr


def test_the_summary_indexes_each_chunk_as_the_chunk_describes_itself(recorded):
    """Each chunk index of the summary, read with the mcap library, says what its chunk record says: where it starts,
    its compressed and uncompressed sizes and its first and last log times (until stop 37 an index gave as the
    uncompressed size that of the chunk's last message index)."""
    from mcap.reader import make_reader
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader
    path = recorded[0]
    with open(path, "rb") as file:
        indexes = make_reader(file).get_summary().chunk_indexes
        assert indexes
        for index in indexes:
            file.seek(index.chunk_start_offset)
            chunk = next(iter(StreamReader(file, skip_magic=True, emit_chunks=True).records))
            assert isinstance(chunk, Chunk)
            assert (index.compressed_size, index.uncompressed_size) == (len(chunk.data), chunk.uncompressed_size)
            assert (index.message_start_time, index.message_end_time) == (chunk.message_start_time,
                                                                        chunk.message_end_time)
