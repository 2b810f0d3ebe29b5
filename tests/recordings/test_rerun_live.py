"""A run shown live in Rerun (``zencosim run --rerun connect=…``) over Zenoh: a headless Rerun gRPC server
started here (``rerun --serve-grpc --save``) receives every series, the same values as the replay of the
same run's recording, and a frame of the mechanism per ``LIVE_FRAME_NS`` of simulated time, each the
replay's frame at that time."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from tests.conftest import wait_for
from tests.recordings.test_rerun_view import _columns
from zencosim.manager.bus.zenoh_session import free_tcp_port
from zencosim.recordings.mechanism import LIVE_FRAME_NS

pytestmark = [pytest.mark.multiprocess, pytest.mark.filterwarnings("ignore:RRD file has no footer")]

RERUN = Path(sys.executable).with_name("rerun")


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


def test_a_live_run_receives_what_the_replay_of_its_recording_shows(processes, tmp_path):
    port = free_tcp_port()
    live, replayed, mcap = tmp_path / "live.rrd", tmp_path / "replay.rrd", tmp_path / "run.mcap"
    sink = subprocess.Popen([str(RERUN), "--serve-grpc", "--port", str(port), "--save", str(live)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        wait_for(lambda: live.exists(), 30, "the Rerun sink to listen")
        run = processes("run", "two_mass_damped", "--bus", "zenoh", "--set", "manager.duration=1.0", "--quiet",
                        "--record", str(mcap), "--rerun", f"connect=127.0.0.1:{port}")
        _, stderr = run.communicate(timeout=120)
        assert run.returncode == 0, stderr
    finally:
        os.killpg(sink.pid, signal.SIGINT)  # the sink writes what it received and exits
        try:
            sink.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(sink.pid, signal.SIGKILL)
            sink.wait()
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
