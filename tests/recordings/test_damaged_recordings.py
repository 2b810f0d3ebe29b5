"""Damaged recordings: a clean RecordingError or a correct verdict, never a traceback and never a false pass.

Damaged copies of a real recording (tests/recordings/corruption.py: bit flips, truncations, two
chunks swapped, byte ranges zeroed, a flip in a record outside the chunks) go through what
``zencosim inspect`` and ``zencosim replay --verify`` call. Every byte of a finished recording is
checked — the data section by its CRC and by the end record's SHA-256 of everything before it (the
metadata and the scene among it), every chunk by its CRC, the summary and the footer's fields by the
summary CRC, the closing magic by comparison — so the verdict is exact: a copy *passes* (inspect: read
to its end with no damage; verify: that, and every message bit-identical to a re-run) only when it is
byte for byte the intact file; any other copy gives a RecordingError or a verdict that names the damage.
"""
from __future__ import annotations

import subprocess
import sys
import tracemalloc

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zencosim
from tests.conftest import REPO
from tests.recordings.corruption import KINDS, claiming_duration, corrupt, emptied, records
from zencosim.recordings import RecordingError
from zencosim.recordings.reader import describe, read_recording
from zencosim.recordings.verify import verify

pytestmark = pytest.mark.multiprocess


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> bytes:
    """A recording of two_mass_damped paced to the wall clock for 1.2 s: the recorder writes a chunk every
    0.5 s, so the file holds several chunks (at least two: asserted)."""
    path = tmp_path_factory.mktemp("damaged") / "run.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=1.2"]), record=path, realtime=True)
    data = path.read_bytes()
    assert sum(opcode == 0x06 for opcode, _, _ in records(data)) >= 2
    return data


def _verdicts(path) -> tuple[bool, bool] | None:
    """(whether inspect finds the file intact, whether verify passes), from one reading of the file (as both
    commands read it); None for a RecordingError naming the file."""
    try:
        recording = read_recording(path)
        info = describe(recording)
        result = verify(recording)
    except RecordingError as error:
        assert str(path) in str(error)
        return None
    assert info["complete"] == (recording.truncated is None) and info["damage"] == recording.damage
    assert result.passed == (result.divergence is None and not result.note and not result.damage
                             and result.truncated is None)
    return recording.intact, result.passed


def test_the_intact_recording_passes(intact, tmp_path):
    path = tmp_path / "intact.mcap"
    path.write_bytes(intact)
    assert _verdicts(path) == (True, True)


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(KINDS), a=st.integers(0, 1 << 40), b=st.integers(0, 1 << 40))
def test_a_damaged_recording_never_passes(intact, tmp_path, kind, a, b):
    data = corrupt(intact, kind, a, b)
    path = tmp_path / f"{kind}.mcap"
    path.write_bytes(data)
    verdicts = _verdicts(path)
    if data == intact:
        assert verdicts == (True, True)
    else:
        assert verdicts is None or verdicts == (False, False), verdicts


def _zencosim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, cwd=REPO,
                          timeout=120)


def test_the_command_line_names_the_damage_and_exits_non_zero(intact, tmp_path):
    name = intact.index(b"two_mass_damped")  # the scene's name in the run's metadata record
    flipped = tmp_path / "flipped.mcap"
    flipped.write_bytes(intact[:name] + b"uwo" + intact[name + 3:])
    result = _zencosim("replay", str(flipped), "--verify")
    assert result.returncode == 1 and "verify FAILED: the file is damaged" in result.stdout, result.stdout
    assert "SHA-256" in result.stdout
    result = _zencosim("inspect", str(flipped))
    assert result.returncode == 1 and "damaged:" in result.stdout, result.stdout

    short = tmp_path / "short.mcap"
    short.write_bytes(intact[:100])
    result = _zencosim("inspect", str(short))
    assert result.returncode == 2 and f"{short} is a cut-off or damaged recording" in result.stderr, result.stderr
    assert "Traceback" not in result.stderr

    cut = tmp_path / "cut.mcap"  # cut inside the last chunk: the chunks before it are verified
    last_chunk = max(start for opcode, start, _ in records(intact) if opcode == 0x06)
    cut.write_bytes(intact[:last_chunk + 50])
    result = _zencosim("replay", str(cut), "--verify")
    assert result.returncode == 1 and "verify INCOMPLETE" in result.stdout and "the end record" in result.stdout
    assert "bit-identical to a re-run" in result.stdout, result.stdout


def test_a_small_file_claiming_a_huge_run_allocates_nothing_of_it(tmp_path):
    """A 10-step recording rewritten to claim 1e7 s (1e10 macro-steps: 149 GiB of residual arrays) and hold no
    message: verify plans its re-run for the statuses the file holds (none, plus one), so it allocates about
    what a one-step run does; 64 MiB bounds that with a wide margin and is a thousandth of one array of the
    claimed run."""
    small = tmp_path / "small.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=0.01"]), record=small)
    crafted = claiming_duration(small, tmp_path / "crafted.mcap", 1e7)
    tracemalloc.start()
    try:
        result = verify(read_recording(crafted))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 64 << 20, peak
    assert not result.passed and result.completed_run and "holds no message" in result.note, result


def test_a_recording_without_messages_never_passes(tmp_path):
    """A run that failed or was interrupted before its first message leaves an intact file with no message: it
    verifies nothing, so it fails (exit 1) with a line that says so, whatever its end record says."""
    small = tmp_path / "small.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=0.01"]), record=small)
    for outcome in ("failed", "interrupted", "completed"):
        empty = emptied(small, tmp_path / f"{outcome}.mcap", outcome)
        result = verify(read_recording(empty))
        assert result.empty and not result.passed, (outcome, result)
    result = _zencosim("replay", str(empty), "--verify")
    assert result.returncode == 1, result
    assert result.stdout.strip() == f"verify FAILED: {empty} holds no messages to verify", result.stdout
    result = _zencosim("replay", str(tmp_path / "failed.mcap"), "--verify")
    assert result.returncode == 1 and "holds no messages to verify" in result.stdout, result.stdout
    assert "Traceback" not in result.stderr
