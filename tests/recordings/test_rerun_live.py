"""A run shown live in Rerun (``zencosim run --rerun connect=…``) over Zenoh: a headless Rerun gRPC server
started here (``rerun --serve-grpc --save``) receives every series, the same values as the replay of the
same run's recording, and a frame of the mechanism per ``LIVE_FRAME_NS`` of simulated time, each the
replay's frame at that time."""
from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from tests.conftest import wait_for
from tests.recordings.test_rerun_view import RERUN, _columns
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.bus.zenoh_session import free_tcp_port
from zencosim.manager.scene.load import load_scene
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.mechanism import LIVE_FRAME_NS
from zencosim.recordings.recorder import Recorder

pytestmark = [pytest.mark.multiprocess, pytest.mark.filterwarnings("ignore:RRD file has no footer")]


def _logged(rrd: Path) -> dict[str, dict[int, bytes]]:
    """Entity → {sim_time [ns]: the bytes of what was logged there} of every time-indexed row of the file."""
    from rerun.chunk import RrdReader
    found: dict[str, dict[int, bytes]] = defaultdict(dict)
    for entity, table in _columns(RrdReader(rrd).stream()).items():
        if "sim_time" not in table.column_names or entity == "/events":
            continue
        rows = table.filter(pc.is_valid(table["sim_time"]))
        data = [c for c in rows.column_names if ":" in c and c.split(":")[1] in ("scalars", "centers", "strips",
                                                                                    "vectors", "origins")]
        for i, time_ns in enumerate(rows["sim_time"].cast(pa.int64()).to_pylist()):
            found[entity][time_ns] = repr([rows[c][i].as_py() for c in data]).encode()
    return found


@contextlib.contextmanager
def _sink(rrd: Path):
    """A headless Rerun gRPC server that saves what it receives to ``rrd`` once the block ends; its address."""
    port = free_tcp_port()
    sink = subprocess.Popen([str(RERUN), "--serve-grpc", "--port", str(port), "--save", str(rrd)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        wait_for(lambda: rrd.exists(), 30, "the Rerun sink to listen")
        yield f"127.0.0.1:{port}"
    finally:
        os.killpg(sink.pid, signal.SIGINT)  # the sink writes what it received and exits
        try:
            sink.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(sink.pid, signal.SIGKILL)
            sink.wait()


@pytest.mark.parametrize("bus", ["zenoh", "inproc"])  # in process, the view builds the messages from ROWS frames
def test_a_live_run_receives_what_the_replay_of_its_recording_shows(processes, tmp_path, bus):
    live, replayed, mcap = tmp_path / "live.rrd", tmp_path / "replay.rrd", tmp_path / "run.mcap"
    with _sink(live) as address:
        run = processes("run", "two_mass_damped", "--bus", bus, "--set", "manager.duration=1.0", "--quiet",
                        "--record", str(mcap), "--rerun", f"connect={address}")
        _, stderr = run.communicate(timeout=120)
        assert run.returncode == 0, stderr
    replay = processes("replay", str(mcap), "--rrd", str(replayed))
    _, stderr = replay.communicate(timeout=120)
    assert replay.returncode == 0, stderr

    shown, expected = _logged(live), _logged(replayed)
    assert set(shown) == set(expected)
    assert {"/positions/S2/x2", "/residual_power/c", "/mechanism/S2/bodies", "/mechanism/forces/c"} <= set(shown)
    for entity, rows in expected.items():
        if entity.startswith("/mechanism/"):  # a frame per LIVE_FRAME_NS of simulated time, each the replay's
            assert sorted(shown[entity]) == list(range(0, 1_000_000_001, LIVE_FRAME_NS)), entity
            assert shown[entity] == {t: rows[t] for t in shown[entity]}, entity
        else:
            assert shown[entity] == rows, entity  # every time, every value, bit for bit
    assert len(expected["/positions/S2/x2"]) == 1001 and len(expected["/mechanism/S1/bodies"]) == 1001
    assert np.all(np.diff(sorted(expected["/residual_power/c"])) == 1_000_000)


def test_a_live_view_that_falls_behind_is_skipped_not_waited_for(tmp_path):
    """The live view is frozen (SIGSTOP) once ready, for a recorded in-process run of 30 000 steps: its pipe
    fills, and the batches after that are skipped instead of waited for (a wait longer than the scene's
    timeout fails the test), while the recording still gets every message. Thawed, the view says the gap
    on its timeline and draws no mechanism after it."""
    from rerun.chunk import RrdReader
    said: list[str] = []

    def announce(text: str) -> None:
        said.append(text)
        assert "has taken nothing" not in text, text  # the run waited for an observer

    scene = load_scene("two_mass_damped", ["manager.duration=30", "manager.timeout=10"])
    plan, subsystems = plan_scene(scene)
    status = StatusReport(plan, realtime=False)
    live, mcap = tmp_path / "live.rrd", tmp_path / "run.mcap"
    with _sink(live) as address:
        recorder = Recorder(mcap, rerun=f"connect={address}", announce=announce)
        try:
            recorder.start(scene, plan, status, "inproc", "behind", realtime=False)
            view = recorder.pids[1]
            os.kill(view, signal.SIGSTOP)
            try:
                # as zencosim run makes it: the scheme calls the subsystems and hands the recorder ROWS frames
                run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems),
                                           tap=recorder), plan, subsystems, recorder)
            finally:
                os.kill(view, signal.SIGCONT)
            end = recorder.finish("completed")
        finally:
            recorder.close()
    assert end["lost"] == 0 and end["messages"] == sum(recorder.published.values())
    behind = [text for text in said if text.startswith("the live view fell behind the run")]
    assert len(behind) == 1 and "the recording holds every step" in behind[0], said
    batches, steps = recorder.live_skipped
    assert batches > 0 and f"{batches} batches ({steps} macro-steps)" in behind[0]
    shown = _columns(RrdReader(live).stream())
    events = [text for texts in shown["/events"]["TextLog:text"].to_pylist() if texts for text in texts]
    gap = [text for text in events if "the live view fell behind the run" in text]
    assert len(gap) == 1, events
    first, last = (int(step) for step in gap[0].split("steps ")[1].split(" ")[0].split("–"))
    power = shown["/residual_power/c"]  # from the status, which opens each step of a batch
    times = sorted(power.filter(pc.is_valid(power["sim_time"]))["sim_time"].cast(pa.int64()).to_pylist())
    assert times[:first - 1] == [step * 1_000_000 for step in range(1, first)]  # every step before the gap
    assert not any(first * 1_000_000 <= t <= last * 1_000_000 for t in times)
    assert times[first - 1:] == [step * 1_000_000 for step in range(last + 1, 30_001)]  # and every step after it
    bodies = shown["/mechanism/S2/bodies"]
    drawn = bodies.filter(pc.is_valid(bodies["sim_time"]))["sim_time"].cast(pa.int64()).to_pylist()
    assert drawn and max(drawn) < first * 1_000_000
