"""Recorded runs with real processes and real Zenoh on loopback: nothing lost, every step kept, replayable.

Every process a test starts is killed at its end (tests.conftest.processes); the recorder is a
child of the manager and dies with it.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import alive, children_of, cmdline, wait_for
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.reader import read_recording
from zencosim.recordings.recorder_process import NO_END
from zencosim.recordings.rerun_view import series_of
from zencosim.recordings.verify import verify

pytestmark = pytest.mark.multiprocess


def _child(manager_pid: int, marker: str) -> int | None:
    """The child process of the manager whose command line contains ``marker``."""
    return next((pid for pid in children_of(manager_pid) if marker in cmdline(pid)), None)


def _assert_contiguous(recording, last_step: int) -> None:
    """Every channel holds every step from the first to ``last_step`` (outputs may hold one more)."""
    status_steps = [m.step for m in recording.channels["manager/status"].messages]
    assert status_steps == list(range(1, last_step + 1))
    for topic, channel in recording.channels.items():
        if topic.endswith("/y"):
            steps = [m.step for m in channel.messages if m.kind == Kind.OUTPUT]
            assert steps[:last_step + 1] == list(range(last_step + 1)), topic
        elif topic.endswith("/commands"):
            steps = [m.step for m in channel.messages if m.kind in (Kind.INIT, Kind.STEP)]
            assert steps[:last_step + 1] == [0] + list(range(last_step)), topic


@pytest.mark.timeout(180)
def test_a_zenoh_run_at_1_ms_over_10_s_is_recorded_without_loss_and_replays(processes, tmp_path, record_property):
    mcap, summary, rrd = tmp_path / "run.mcap", tmp_path / "summary.json", tmp_path / "run.rrd"
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--quiet", "--record", str(mcap),
                        "--summary", str(summary))
    recorder = wait_for(lambda: _child(manager.pid, "zencosim.recordings.recorder_process"), 30, "the recorder process")
    wait_for(lambda: mcap.exists() and mcap.stat().st_size > 100_000, 60, "the recording to grow")
    slowed = time.monotonic()
    # a recorder at a tenth of its speed for up to 4 s: its pipe must hold up the manager's replica, not
    # drop; it may finish within the window (the subsystems do not wait for it), which ends the slowing
    try:
        while time.monotonic() - slowed < 4.0:
            os.kill(recorder, signal.SIGSTOP)
            time.sleep(0.09)
            os.kill(recorder, signal.SIGCONT)
            time.sleep(0.01)
    except ProcessLookupError:
        pass
    finally:
        if alive(recorder):
            os.kill(recorder, signal.SIGCONT)
    record_property("recorder_slowed_s", time.monotonic() - slowed)
    _, stderr = manager.communicate(timeout=150)
    assert manager.returncode == 0, stderr

    recording_summary = json.loads(summary.read_text())["recording"]
    assert recording_summary["lost"] == 0
    expected = {"S1/commands": 10001, "S1/y": 10001, "S2/commands": 10001, "S2/y": 10001, "manager/status": 10000}
    for topic, counts in recording_summary["channels"].items():
        assert counts["published"] == counts["received"] == expected[topic], topic

    recording = read_recording(mcap)
    assert recording.truncated is None and recording.info["bus"] == "zenoh"
    _assert_contiguous(recording, 10000)
    _, _, status = recording.channels["manager/status"].table(Kind.STATUS)
    names = recording.channels["manager/status"].spec.names
    record_property("longest_step_s", float(np.max(status[:, names.index("step_wall_time")])))

    replay = subprocess.run([sys.executable, "-m", "zencosim", "replay", str(mcap), "--verify", "--rrd", str(rrd)],
                            capture_output=True, text=True, timeout=120)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    assert "verify passed: 50004 messages" in replay.stdout
    _assert_rrd_holds(rrd, _series(recording))


def _series(recording) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Entity → (steps, times [ns], values) of every series the replay shows: each output, each received
    input's value at the start of each step, each status field (timing in µs)."""
    found = {}
    for channel in recording.channels.values():
        kind = {"outputs": Kind.OUTPUT, "inputs": Kind.STEP, "status": Kind.STATUS}[channel.spec.role]
        steps, times, values = channel.table(kind)
        for series in series_of(channel.spec, (0, 0, 0)):
            kept = ~np.isnan(values[:, series.column])  # the replay leaves NaN out
            found[series.entity] = (steps[kept], times[kept], values[kept, series.column] * series.scale)
    return found


def _assert_rrd_holds(rrd: Path, series: dict) -> None:
    """The Rerun file holds every series of the recording: the same steps, times [ns] and float64 bits."""
    import pyarrow as pa
    from rerun.chunk import RrdReader
    found: dict[str, list] = {}
    for chunk in RrdReader(rrd).stream():
        if chunk.entity_path in series and "step" in chunk.to_record_batch().schema.names:
            found.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    assert set(found) == set(series)
    for entity, (steps, times, values) in series.items():
        table = pa.Table.from_batches(found[entity]).sort_by("step")
        assert table["step"].to_numpy().tolist() == steps.tolist(), entity
        assert table["sim_time"].cast(pa.int64()).to_numpy().tolist() == times.tolist(), entity
        logged = table["Scalars:scalars"].combine_chunks().flatten().to_numpy(zero_copy_only=False)
        assert logged.view(np.uint64).tolist() == values.view(np.uint64).tolist(), entity


def _start_long_recorded_run(processes, mcap: Path, bus: str, timeout_s: float = 5.0):
    """A recorded run of 600 s of simulated time, well under way when this returns."""
    manager = processes("run", "two_mass_damped", "--bus", bus, "--quiet", "--record", str(mcap),
                        "--set", "manager.duration=600", "--set", f"manager.timeout={timeout_s}")
    wait_for(lambda: _child(manager.pid, "zencosim.recordings.recorder_process"), 30, "the recorder process")
    wait_for(lambda: mcap.exists() and mcap.stat().st_size > 50_000, 60, "the recording to grow")
    assert manager.poll() is None, manager.communicate()
    return manager


@pytest.mark.timeout(120)
def test_a_run_whose_subsystem_was_killed_leaves_every_step_before_the_crash(processes, tmp_path):
    mcap = tmp_path / "crash.mcap"
    manager = _start_long_recorded_run(processes, mcap, "zenoh")
    os.kill(_child(manager.pid, "two_mass_damped.toml S2 "), signal.SIGKILL)
    _, stderr = manager.communicate(timeout=60)
    assert manager.returncode == 1 and "subsystem S2:" in stderr
    assert f"recording {mcap}" in stderr and "lost" in stderr

    recording = read_recording(mcap)
    assert recording.truncated is None  # finished properly by the recorder
    assert recording.end["outcome"].startswith("failed: subsystem S2") and recording.end["lost"] == 0
    last = recording.last_step()
    assert last > 100
    _assert_contiguous(recording, last)
    result = verify(recording)  # every step before the crash is bit-identical to a re-run
    assert result.divergence is None and result.last_step == last, result


@pytest.mark.timeout(120)
@pytest.mark.parametrize("bus, signum", [("inproc", signal.SIGTERM), ("inproc", signal.SIGINT), ("zenoh", signal.SIGINT)],
                         ids=["inproc-SIGTERM", "inproc-SIGINT", "zenoh-SIGINT"])
def test_a_signalled_run_finishes_its_recording(processes, tmp_path, bus, signum):
    mcap = tmp_path / "signalled.mcap"
    manager = _start_long_recorded_run(processes, mcap, bus)
    manager.send_signal(signum)
    _, stderr = manager.communicate(timeout=60)
    assert manager.returncode == 130, stderr
    recording = read_recording(mcap)
    assert recording.truncated is None
    assert recording.end["outcome"] == "interrupted" and recording.end["lost"] == 0
    _assert_contiguous(recording, recording.last_step())
    assert verify(recording).divergence is None


@pytest.mark.timeout(120)
def test_a_killed_manager_takes_the_recorder_with_it_and_leaves_a_readable_file(processes, tmp_path):
    mcap = tmp_path / "orphan.mcap"
    manager = _start_long_recorded_run(processes, mcap, "zenoh")
    children = children_of(manager.pid)
    manager.kill()
    manager.communicate(timeout=30)
    try:
        wait_for(lambda: not any(alive(pid) for pid in children), 30, "the subsystems and the recorder to exit")
    except AssertionError as error:
        raise AssertionError(f"{error}; still alive: {[cmdline(pid) for pid in children if alive(pid)]}") from None
    recording = read_recording(mcap)
    assert recording.truncated is None  # the recorder got SIGTERM from the kernel and finished the file
    assert NO_END in recording.end["outcome"]  # seen as SIGTERM or as the end of its input, whichever came first
    _assert_contiguous(recording, recording.last_step())
