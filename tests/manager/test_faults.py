"""Faults and stray traffic during real runs (real processes, real Zenoh on loopback): each is named in one
line, never a traceback, and a stray or garbled message never changes a run's result.

Every process a test starts is killed at its end (tests.conftest.processes). No assertion on wall-clock
time: a test waits for what it needs to see (a line, a file, an answer), with generous limits.
"""
from __future__ import annotations

import json
import os
import pty
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

import zencosim.examples
from tests.conftest import alive, busy_prefix, children_of, cmdline, end_busy, read_until, summary_of, wait_for
from tests.interop.peer_pair import write_system
from zencosim.manager.bus.children import cpu_time_s
from zencosim.manager.bus.zenoh_session import free_tcp_port, key, session_config, wait_for_listener
from zencosim.manager.wire.protocol import Kind, encode, encode_error
from zencosim.recordings.reader import read_recording

pytestmark = pytest.mark.multiprocess


def _child(manager_pid: int, marker: str) -> int | None:
    """The child process of the manager whose command line contains ``marker``."""
    return next((pid for pid in children_of(manager_pid) if marker in cmdline(pid)), None)


def _joined(port: int, wait_s: float = 60.0) -> tuple[zenoh.Session, dict]:
    """A session of the test linked to the manager listening on ``port`` and to every subsystem process of its run
    (peers do not forward: a message for a subsystem must be published on a link to it), and the run's description."""
    wait_for_listener(f"tcp/127.0.0.1:{port}", wait_s)
    with zenoh.open(session_config(connect=[f"tcp/127.0.0.1:{port}"], mode="client")) as probe:
        def described():
            answers = [r.ok for r in probe.get("zencosim/*/manager/run", timeout=1.0) if r.ok is not None]
            info = json.loads(answers[0].payload.to_bytes()) if answers else None
            return info if info and not info["waiting_for"] else None
        info = wait_for(described, wait_s, "the run to describe itself with every subsystem joined")
    peers = [f"tcp/127.0.0.1:{port}", *info["endpoints"].values()]
    return zenoh.open(session_config(connect=peers)), info


def _run_with_stray_traffic(processes, tmp_path, inject) -> tuple[object, str, dict | None]:
    """A real-time zenoh run of 5 s of two_mass_damped (so that it lasts while the test injects), with ``inject(session,
    run_id)`` called once the run has started; (manager, its stderr, its summary or None)."""
    port, summary = free_tcp_port(), tmp_path / "summary.json"
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--realtime", "--set", "manager.duration=5",
                        "--set", "manager.timeout=3", "--listen", f"tcp/127.0.0.1:{port}", "--summary", str(summary))
    session, info = _joined(port)
    try:
        read_until(manager.stderr, "starting", 60)
        inject(session, info["run_id"])
        assert manager.poll() is None, "the run ended before the stray messages were sent: inconclusive"
        _, stderr = manager.communicate(timeout=120)
    finally:
        session.close()
    return manager, stderr, json.loads(summary.read_text()) if summary.exists() else None


@pytest.mark.timeout(240)
def test_stray_and_garbled_messages_are_dropped_counted_and_leave_the_result_unchanged(processes, tmp_path):
    garbage = bytes([0xEE]) + random.Random(14).randbytes(99)  # 100 random bytes (not protocol version 2)
    replayed: list[bytes] = []

    def inject(session: zenoh.Session, run_id: str) -> None:
        tap = session.declare_subscriber(key(run_id, "S1", "log"), lambda sample: replayed.append(
            sample.payload.to_bytes()))
        wait_for(lambda: replayed, 30, "a batch of S1's replies to replay")
        tap.undeclare()
        session.put(key(run_id, "X", "log"), encode(Kind.OUTPUT, 1, 1_000_000, np.ones(2), ref=7))
        session.put(key(run_id, "S1", "y"), garbage)  # S2 takes S1's replies from here
        session.put(key(run_id, "S1", "log"), replayed[0])  # the manager takes them from here, in batches
        session.put(key(run_id, "S1", "log"), garbage)

    manager, stderr, summary = _run_with_stray_traffic(processes, tmp_path, inject)
    assert manager.returncode == 0, stderr
    assert "Traceback" not in stderr
    assert summary["digest"] == summary_of("two_mass_damped", "manager.duration=5")["digest"]
    dropped = summary["dropped_messages"]
    run_id = next(iter(dropped)).split("/")[1]
    on = {topic: dropped.get(key(run_id, *topic.split("/"))) for topic in ("X/log", "S1/y", "S1/log")}
    assert on["X/log"] == {"count": 1, "reason": "no subsystem of this run publishes on this key", "publisher": None,
                           "seen_by": ["manager"]}
    assert on["S1/y"]["count"] == 1 and on["S1/y"]["seen_by"] == ["S2"]
    assert "protocol version 238" in on["S1/y"]["reason"]
    # the replayed batch: each of its replies (48 bytes) answers a command already answered, or its copy that
    # arrived first did and the original is dropped; and the garbage, as one malformed batch or as its parts
    assert on["S1/log"]["count"] >= len(replayed[0]) // 48 + 1 and on["S1/log"]["seen_by"] == ["manager"]


@pytest.mark.timeout(240)
def test_a_forged_error_fails_the_run_with_its_text_escaped(processes, tmp_path):
    def inject(session: zenoh.Session, run_id: str) -> None:
        # an ERROR on S1/y cannot be checked by S2, which does not compute S1's commands: it ends the run
        for step in range(0, 5000, 50):
            session.put(key(run_id, "S1", "y"), encode_error(step, 0, "\x1b]0;owned\x07\x1b[2Jgone"))

    manager, stderr, _ = _run_with_stray_traffic(processes, tmp_path, inject)
    assert manager.returncode == 1 and "Traceback" not in stderr
    assert "subsystem S2:" in stderr and "subsystem S1: failed at step" in stderr
    assert "\x1b" not in stderr and "\x07" not in stderr and "\\x1b]0;owned\\x07\\x1b[2Jgone" in stderr


@pytest.mark.timeout(240)
def test_a_stop_the_manager_did_not_send_is_named_as_coming_from_elsewhere(processes, tmp_path):
    """A peer of the test's own (no credentials, as any local process on a default loopback run) publishes a
    STOP on S1's control key: the run fails naming where it came from, never as stopped by the manager."""
    def inject(session: zenoh.Session, run_id: str) -> None:
        session.put(key(run_id, "S1", "u"), encode(Kind.STOP, 0, 0))

    manager, stderr, _ = _run_with_stray_traffic(processes, tmp_path, inject)
    assert manager.returncode == 1 and "Traceback" not in stderr
    assert stderr.startswith("run failed: subsystem S1: a STOP that the manager did not send ended its process: "
                             "another process that reaches the run published it on zencosim/"), stderr
    assert "stopped by the manager" not in stderr


@pytest.mark.timeout(60)
def test_an_occupied_listen_port_is_one_line(processes):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--listen", f"tcp/127.0.0.1:{port}")
        _, stderr = manager.communicate(timeout=60)
    assert manager.returncode == 2
    assert stderr.strip() == f"error: cannot listen on tcp/127.0.0.1:{port}: address already in use"


def _recorded_run(processes, mcap, bus: str, *options: str):
    manager = processes("run", "two_mass_damped", "--bus", bus, "--record", str(mcap), *options)
    recorder = wait_for(lambda: _child(manager.pid, "zencosim.recordings.recorder_process"), 60, "the recorder")
    wait_for(lambda: mcap.exists() and mcap.stat().st_size > 50_000, 60, "the recording to grow")
    assert manager.poll() is None, manager.communicate()
    return manager, recorder


@pytest.mark.timeout(120)
@pytest.mark.parametrize("bus", ["inproc", "zenoh"])
def test_a_killed_recorder_stops_the_run_in_one_line(processes, tmp_path, bus):
    mcap = tmp_path / "killed.mcap"
    manager, recorder = _recorded_run(processes, mcap, bus, "--quiet", "--set", "manager.duration=600")
    os.kill(recorder, signal.SIGKILL)
    _, stderr = manager.communicate(timeout=60)
    assert manager.returncode == 1 and "Traceback" not in stderr, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"run failed: the recorder of {mcap} is gone (killed by SIGKILL) "
                                                   "at step "), stderr
    step = int(lines[0].split(" at step ")[1].split(":")[0])
    recording = read_recording(mcap)  # cut off: what it holds ends before the step the run had reached
    assert recording.truncated is not None and 0 < recording.last_step() <= step


@pytest.mark.timeout(180)
def test_a_killed_recorder_under_record_lost_continue_leaves_the_run_to_finish(processes, tmp_path):
    mcap, summary = tmp_path / "killed.mcap", tmp_path / "summary.json"
    manager, recorder = _recorded_run(processes, mcap, "zenoh", "--quiet", "--record-lost", "continue",
                                      "--set", "manager.duration=20", "--summary", str(summary))
    os.kill(recorder, signal.SIGKILL)
    _, stderr = manager.communicate(timeout=150)
    assert manager.returncode == 0, stderr
    assert stderr.startswith(f"the recorder of {mcap} is gone (killed by SIGKILL) at step ") and "Traceback" not in stderr
    assert "the run goes on unrecorded (--record-lost continue)" in stderr
    result = json.loads(summary.read_text())
    assert result["recording"]["outcome"].startswith("the recorder was lost at step ")
    assert result["recording"]["outcome"].endswith("(killed by SIGKILL); the run: completed")
    assert result["digest"] == summary_of("two_mass_damped", "manager.duration=20")["digest"]


@pytest.mark.timeout(240)
def test_a_frozen_recorder_holds_the_run_back_and_is_named_not_a_subsystem(processes, tmp_path):
    """The recorder is stopped until the subsystems have finished and the manager has heard nothing from them
    for longer than manager.timeout: the run waits for it, says so, and completes with nothing lost."""
    mcap, port = tmp_path / "frozen.mcap", free_tcp_port()
    manager, recorder = _recorded_run(processes, mcap, "zenoh", "--set", "manager.duration=20",
                                      "--set", "manager.timeout=1", "--listen", f"tcp/127.0.0.1:{port}")
    os.kill(recorder, signal.SIGSTOP)
    try:
        lines = read_until(manager.stderr, "has taken nothing for 1 s", 120)
        wait_for_listener(f"tcp/127.0.0.1:{port}", 60)
        with zenoh.open(session_config(connect=[f"tcp/127.0.0.1:{port}"], mode="client")) as session:
            run_id = json.loads(next(r.ok for r in session.get("zencosim/*/manager/run", timeout=5.0)
                                     if r.ok is not None).payload.to_bytes())["run_id"]
            for name in ("S1", "S2"):  # finished: they answer with their timing
                wait_for(lambda: any(r.ok for r in session.get(key(run_id, name, "timing"), timeout=1.0)), 120,
                         f"{name} to finish")
        time.sleep(3 * 1.0)  # longer than manager.timeout without a batch: what a subsystem stall would look like
    finally:
        if alive(recorder):
            os.kill(recorder, signal.SIGCONT)
    _, rest = manager.communicate(timeout=120)
    stderr = "".join(lines) + rest
    assert manager.returncode == 0, stderr
    assert ("its process is frozen (process stopped, state T: SIGSTOP or a debugger); the run waits for it "
            "(nothing is dropped)") in stderr
    assert "did not answer" not in stderr and "takes messages again after" in stderr
    recording = read_recording(mcap)
    assert recording.truncated is None and recording.end["outcome"] == "completed" and recording.end["lost"] == 0


# The example model with a fault, chosen by the environment variable FAULT, once its time reaches FAULT_T [s] (10 ms)
FAULTY_MODEL = """
import ctypes, os, sys, time
from zencosim.examples.oscillator import Oscillator

FAULT_T = float(os.environ.get("FAULT_T", "0.01"))


class Faulty(Oscillator):
    def __init__(self, **parameters):
        if os.environ["FAULT"] == "init":
            raise RuntimeError("cannot open its lookup table")
        if os.environ["FAULT"] == "init-exit":
            os._exit(0)
        super().__init__(**parameters)

    def acceleration(self, t, z, u):
        fault = os.environ["FAULT"]
        if t >= FAULT_T:
            if fault == "exit":
                sys.exit(0)
            if fault == "interrupt":
                raise KeyboardInterrupt
            if fault == "hang":
                time.sleep(600)
            while fault == "spin":
                pass
            if fault == "os-exit":
                os._exit(0)
            if fault == "segfault":
                ctypes.string_at(0)
            if fault == "abort":
                os.abort()
        return super().acceleration(t, z, u)
"""


def _faulty_env(tmp_path, fault: str, fault_t: float = 0.01) -> dict[str, str]:
    """The environment of a command that runs the faulty model of ``tmp_path``: failing by ``fault`` from ``fault_t``."""
    path = os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path, "FAULT": fault, "FAULT_T": repr(fault_t)}


def _faulty_run(processes, tmp_path, fault: str, bus: str, *options: str, duration: float = 0.5,
                fault_t: float = 0.01):
    """The example two_mass_damped_python scene (1 ms steps) with S2's model failing by ``fault`` from ``fault_t`` [s],
    run for ``duration`` [s]: the finished manager's exit status and standard error."""
    (tmp_path / "faulty_model.py").write_text(FAULTY_MODEL)
    scene = (Path(zencosim.examples.__file__).parent / "scenes" / "two_mass_damped_python.toml").read_text()
    head, _, tail = scene.partition("[subsystems.S2]")
    scene_file = tmp_path / "faulty.toml"
    scene_file.write_text(head + "[subsystems.S2]" + tail.replace("zencosim.examples.oscillator:Oscillator",
                                                                  "faulty_model:Faulty", 1))
    manager = processes("run", str(scene_file), "--bus", bus, "--quiet", "--set", f"manager.duration={duration}",
                        *options, env=_faulty_env(tmp_path, fault, fault_t))
    _, stderr = manager.communicate(timeout=120)
    return manager.returncode, stderr


def _zencosim(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    """``zencosim ARGS``, finished."""
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, env=env,
                          timeout=120)


CRASH_T_S = 1.5  # [s] the recorded model ends its process in its first step that reaches this
COMPUTED_STEPS = 1499  # the macro-steps of 1 ms the run completes before: its step from t = 1.499 s never ends


@pytest.mark.timeout(240)
@pytest.mark.parametrize("bus, fault", [("inproc", "os-exit"), ("inproc", "segfault"),
                                        pytest.param("zenoh", "segfault", marks=pytest.mark.slow)])
def test_a_recorded_run_whose_model_ends_its_process_keeps_what_it_computed(processes, tmp_path, bus, fault):
    """The model ends its process in the step from t = 1.499 s: the recording keeps at least 95 % of the 1,499 steps
    the run completed (in process the loop hands over what it holds every max(16, a 32nd of its steps), and the
    recorder records what was in its pipe; over Zenoh each subsystem's batches for the manager are as small early in a
    run), the command returns once the file is finished (inspect, run at once, reads it whole), and inspect and
    replay --verify agree on its last step."""
    mcap = tmp_path / "crash.mcap"
    status, stderr = _faulty_run(processes, tmp_path, fault, bus, "--record", str(mcap), duration=2 * CRASH_T_S,
                                 fault_t=CRASH_T_S)
    assert status == 1 and "Traceback" not in stderr, stderr
    if bus == "inproc":  # the step it ended the process in, as the watching parent names it
        assert "the model ended the run's process in its step from t = 1.499 s" in stderr, stderr
    env = _faulty_env(tmp_path, fault, CRASH_T_S)
    inspect = _zencosim(env, "inspect", str(mcap))
    assert inspect.returncode == 0, inspect.stdout + inspect.stderr  # read to its end, intact
    kept = int(re.search(r"steps (\d+) of 3000", inspect.stdout)[1])
    assert 0.95 * COMPUTED_STEPS <= kept <= COMPUTED_STEPS, inspect.stdout
    recording = read_recording(mcap)
    assert recording.last_step() == kept and recording.end is not None
    replay = _zencosim(env, "replay", str(mcap), "--verify")
    messages = sum(len(channel.messages) for channel in recording.channels.values())
    assert f"verify passed: {messages} messages bit-identical to a re-run, up to step {kept}" in replay.stdout, \
        replay.stdout + replay.stderr
    # over Zenoh the manager may have recorded the commands of the step that ended the process (a batch sent just
    # before): then the re-run ends its own process there, after its verdict, and says how (exit status 1)
    assert replay.returncode == 0 or replay.stderr.startswith(
        "the re-run failed: subsystem S2: the model ended the run's process in its step from t = 1.499 s"), replay.stderr


@pytest.mark.timeout(120)
def test_the_replay_of_a_run_that_failed_in_its_model_gives_a_verdict_then_the_reproduced_failure(processes, tmp_path):
    """A model that fails (sys.exit) at t = 0.3 s: replay --verify compares every message the file holds, then says
    that the re-run failed as the run did (exit status 0: the recording verified). The same model ending the process
    there instead (os._exit) ends the re-run's too: the verdict is said before, then how the process ended (1). One
    that fails sooner than the recorded run did fails the verification (1)."""
    mcap, fault_t = tmp_path / "failed.mcap", 0.3
    status, stderr = _faulty_run(processes, tmp_path, "exit", "inproc", "--record", str(mcap), duration=0.6,
                                 fault_t=fault_t)
    failure = "subsystem S2: failed at step 300: the model exited (SystemExit 0)"
    assert status == 1 and stderr.strip().splitlines()[-1] == f"run failed: {failure}", stderr
    recording = read_recording(mcap)
    assert recording.end["outcome"] == f"failed: {failure}" and recording.last_step() == 299
    verdict = (f"verify passed: {sum(len(c.messages) for c in recording.channels.values())} messages bit-identical "
               "to a re-run, up to step 299")

    replay = _zencosim(_faulty_env(tmp_path, "exit", fault_t), "replay", str(mcap), "--verify")
    assert (replay.returncode, replay.stdout.splitlines()) == (0, [verdict, f"the re-run then failed as the run did: "
                                                                           f"{failure}"]), replay.stderr

    replay = _zencosim(_faulty_env(tmp_path, "os-exit", fault_t), "replay", str(mcap), "--verify")
    assert (replay.returncode, replay.stdout.splitlines()) == (1, [verdict]), replay.stderr
    assert re.fullmatch(r"the re-run failed: subsystem S2: the model ended the run's process in its step from t = "
                        r"0\.299 s \(exited with code 0; .*\)", replay.stderr.strip()), replay.stderr

    replay = _zencosim(_faulty_env(tmp_path, "exit", 0.2), "replay", str(mcap), "--verify")
    assert replay.returncode == 1 and replay.stdout.startswith(
        "verify FAILED: the re-run failed before the recording's end (subsystem S2: failed at step 200: the model "
        "exited (SystemExit 0)); the "), replay.stdout + replay.stderr


@pytest.mark.timeout(120)
def test_a_model_that_raises_in_its_constructor_is_named_with_the_exception(processes, tmp_path):
    status, stderr = _faulty_run(processes, tmp_path, "init", "inproc")
    assert status == 2 and "Traceback" not in stderr, stderr
    assert ("subsystems.S2: model faulty_model:Faulty: its constructor raised RuntimeError: cannot open its lookup "
            "table") in stderr


@pytest.mark.timeout(120)
@pytest.mark.parametrize("bus", ["inproc", "zenoh"])
@pytest.mark.parametrize("fault, said", [("exit", "the model exited (SystemExit 0)"),
                                         ("interrupt", "the model raised KeyboardInterrupt (no SIGINT or SIGTERM was "
                                                       "received)")])
def test_a_model_that_exits_or_raises_keyboard_interrupt_fails_the_run_named(processes, tmp_path, bus, fault, said):
    """sys.exit() in a model's step is its failure, not a run that ended well; a KeyboardInterrupt it raises itself
    (no Ctrl-C) is its failure, not the user's interrupt (130)."""
    status, stderr = _faulty_run(processes, tmp_path, fault, bus)
    assert status == 1, stderr
    assert re.fullmatch(rf"run failed: subsystem S2: failed at step \d+: {re.escape(said)}", stderr.strip()), stderr


@pytest.mark.timeout(120)
def test_a_subsystem_that_hangs_in_its_step_is_the_one_named(processes, tmp_path):
    """S2 sleeps in its step; S1, healthy, waits for its reply: S2 is named, never S1 (whose last replies, before
    the wait, reach the manager although S1 publishes nothing new)."""
    status, stderr = _faulty_run(processes, tmp_path, "hang", "zenoh", "--set", "manager.timeout=2")
    assert status == 1 and "Traceback" not in stderr, stderr
    assert stderr.startswith("run failed: subsystem S2: did not answer within the timeout of 2 s (manager.timeout)"), \
        stderr


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_subsystem_that_has_cpu_and_answers_nothing_is_named(processes, tmp_path):
    """S2 loops in its step, on the CPU: however busy the machine, it is named once it has used manager.timeout of
    CPU time without the run advancing, or the stall clock (which counts its CPU share) reaches the timeout."""
    status, stderr = _faulty_run(processes, tmp_path, "spin", "zenoh", "--set", "manager.timeout=1")
    assert status == 1 and "Traceback" not in stderr, stderr
    assert re.match(r"run failed: subsystem S2: did not answer within the timeout of 1 s \(manager\.timeout\)"
                    r"(: its process used \d+\.\d s of CPU time since the run last advanced, and answered nothing)?",
                    stderr), stderr


@pytest.mark.timeout(120)
@pytest.mark.parametrize("fault, ended", [("os-exit", "exited with code 0"), ("segfault", "killed by SIGSEGV"),
                                          ("abort", "killed by SIGABRT")])
def test_a_model_that_ends_the_process_in_process_is_named_with_how(processes, tmp_path, fault, ended):
    """In process a model shares the run's process: one that ends it (os._exit(0), a segmentation fault, abort())
    fails the run with status 1 and names the subsystem, where it was and how the process ended (the command line
    watches its run from a parent process: manager.bus.watchdog)."""
    status, stderr = _faulty_run(processes, tmp_path, fault, "inproc")
    assert status == 1, stderr
    assert re.fullmatch(rf"run failed: subsystem S2: the model ended the run's process in its step from t = "
                        rf"0\.0\d+ s \({ended}; in process every model shares it, over Zenoh each has its own\)",
                        stderr.strip()), stderr


@pytest.mark.timeout(120)
@pytest.mark.parametrize("fault", ["os-exit", "segfault"])
def test_a_model_that_ends_its_process_over_zenoh_is_named(processes, tmp_path, fault):
    """Over Zenoh the same models end only their own subsystem process, which the manager names."""
    status, stderr = _faulty_run(processes, tmp_path, fault, "zenoh")
    assert status == 1, stderr
    assert stderr.startswith("run failed: subsystem S2: process exited with code"), stderr


@pytest.mark.timeout(180)
@pytest.mark.parametrize("bus, said", [
    ("inproc", ("run failed: subsystem mass2: the model ended the run's process in its step from t = 0.01 s (exited "
                "with code 0; in process every model shares it, over Zenoh each has its own)")),
    ("zenoh", "run failed: subsystem mass2: process exited with code 0")])
def test_an_fmu_that_calls_exit_in_its_do_step_is_named(processes, tmp_path, bus, said):
    """The peer pair (tests/interop/peer_pair.py) with mass2's doStep calling the C library's exit(0) from 10 ms:
    no Python exit path runs, and the run still fails naming mass2, on both buses."""
    if shutil.which("gcc") is None:
        pytest.skip("building the peer FMUs needs gcc")
    system = write_system(tmp_path / "system", "plain", mass2="mass2_exits")
    manager = processes("run", str(system), "--bus", bus, "--quiet", "--set", "manager.duration=0.5")
    _, stderr = manager.communicate(timeout=150)
    assert manager.returncode == 1, stderr
    assert stderr.strip().startswith(said), stderr


@pytest.mark.timeout(120)
def test_ctrl_c_at_a_terminal_interrupts_an_in_process_run_once():
    """Ctrl-C at a terminal reaches the watching parent and the run's process (one process group): the parent waits
    for the run to end (it does not pass the terminal's signal on a second time) and the run is interrupted once,
    cleanly (status 130, one line). The run's inputs are first-order holds, which the scheme's own loop steps: 600 s
    of it take seconds (the register program of zero-order ones, a fifth of a second, ended before the signal)."""
    pid, terminal = pty.fork()
    if pid == 0:  # the command on a terminal of its own, as a user starts it
        os.execv(sys.executable, [sys.executable, "-m", "zencosim", "run", "two_mass_damped", "--quiet",
                                  "--set", "manager.duration=600", "--set", "manager.extrapolation=1"])
    said = b""
    try:
        run = wait_for(lambda: children_of(pid), 60, "the run's process")[0]
        wait_for(lambda: cpu_time_s(run) > 0.5, 120, "the run to be under way")
        os.write(terminal, b"\x03")
        while True:
            try:
                chunk = os.read(terminal, 4096)
            except OSError:  # EIO: the terminal's last process has ended
                break
            if not chunk:
                break
            said += chunk
        _, status = os.waitpid(pid, 0)
    finally:
        for process in [pid, *children_of(pid)]:
            if alive(process):
                os.kill(process, signal.SIGKILL)
    text = said.decode(errors="replace")
    assert os.waitstatus_to_exitcode(status) == 130, text
    assert text.count("interrupted") == 1 and "Traceback" not in text, text


@pytest.mark.timeout(120)
def test_a_model_that_ends_the_process_in_its_constructor_is_named(processes, tmp_path):
    status, stderr = _faulty_run(processes, tmp_path, "init-exit", "inproc")
    assert status == 1, stderr
    assert stderr.strip() == ("run failed: subsystem S2: the model ended the run's process in its constructor (exited "
                              "with code 0; in process every model shares it, over Zenoh each has its own)"), stderr


@pytest.mark.timeout(120)
def test_a_model_that_hangs_in_process_is_named_within_the_timeout(processes, tmp_path):
    """The parent process times every call into a model: one that outlasts manager.timeout is ended and named."""
    status, stderr = _faulty_run(processes, tmp_path, "hang", "inproc", "--set", "manager.timeout=2")
    assert status == 1 and "Traceback" not in stderr, stderr
    assert re.fullmatch(r"run failed: subsystem S2: did not answer within the timeout of 2 s \(manager\.timeout\): "
                        r"its step from t = 0\.0\d+ s did not return, and the run's process was ended \(in process "
                        r"every model shares it; over Zenoh each has its own\)", stderr.strip()), stderr


@pytest.mark.timeout(300)
def test_a_recorded_run_starts_on_a_machine_kept_busy(processes, tmp_path):
    """Every core busy with two CPU-bound processes: the recorder starts at normal priority (at idle priority it got
    almost no CPU and did not start within a fixed 30 s) and its start is waited for as long as it makes progress;
    the run completes. The busy processes end once the recording is open: the rest is the recorder's usual work."""
    mcap, pids = tmp_path / "busy.mcap", tmp_path / "busy.pids"
    manager = processes("run", "two_mass_damped", "--record", str(mcap), "--quiet", "--set", "manager.duration=0.1",
                        prefix=busy_prefix(2 * len(os.sched_getaffinity(0)), pids))
    try:
        wait_for(lambda: mcap.exists() or manager.poll() is not None, 280, "the recorder to open the recording")
    finally:
        end_busy(pids)
    _, stderr = manager.communicate(timeout=120)
    assert manager.returncode == 0, stderr
    recording = read_recording(mcap)
    assert recording.truncated is None and recording.end["outcome"] == "completed" and recording.end["lost"] == 0


@pytest.mark.timeout(120)
def test_a_recording_that_cannot_be_written_at_start_says_why(processes, tmp_path):
    """/dev/full takes no byte (ENOSPC): the recorder says so, and the run fails (1), not bad input (2)."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    mcap = tmp_path / "full.mcap"
    mcap.symlink_to("/dev/full")
    manager = processes("run", "two_mass_damped", "--record", str(mcap), "--quiet")
    _, stderr = manager.communicate(timeout=120)
    assert manager.returncode == 1 and "Traceback" not in stderr, stderr
    assert stderr.strip() == (f"run failed: the recorder of {mcap} could not start: writing the file failed: No space "
                              "left on device"), stderr


@pytest.fixture
def tiny_disk(tmp_path):
    """A 64 KiB tmpfs (root, and a system that lets it mount one), unmounted at the end."""
    where = tmp_path / "tiny"
    where.mkdir()
    try:
        mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)],
                                 capture_output=True, text=True)
    except OSError as error:
        pytest.skip(f"cannot mount a tmpfs: {error}")
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {mounted.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


@pytest.mark.timeout(120)
@pytest.mark.parametrize("bus", ["inproc", "zenoh"])
def test_a_full_disk_while_recording_is_named_with_its_cause(processes, tiny_disk, bus):
    mcap = tiny_disk / "run.mcap"
    manager = processes("run", "two_mass_damped", "--bus", bus, "--record", str(mcap), "--quiet")
    _, stderr = manager.communicate(timeout=120)
    assert manager.returncode == 1 and "Traceback" not in stderr, stderr
    assert stderr.startswith(f"run failed: the recorder of {mcap} is gone (exited with code 1: writing the file "
                             "failed: No space left on device) at step "), stderr


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_manager_stopped_longer_than_its_session_lives_names_itself_not_a_subsystem(processes):
    """SIGSTOP on the manager for longer than Zenoh keeps a silent session (10 s): its subsystems lose it and
    stop; the run fails naming the manager's stall first, not a subsystem's session or process as the cause."""
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--realtime", "--set", "manager.duration=60")
    lines = read_until(manager.stderr, "subsystem processes connected, starting", 120)
    time.sleep(1.0)
    os.kill(manager.pid, signal.SIGSTOP)
    try:
        time.sleep(20.0)  # twice the session's lease: a frozen process sends nothing, however loaded the host is
    finally:
        os.kill(manager.pid, signal.SIGCONT)
    _, rest = manager.communicate(timeout=120)
    stderr = "".join(lines) + rest
    assert manager.returncode == 1, stderr
    assert re.search(r"run failed: the manager did not run for (\d+\.\d) s \(its process was stopped or starved of "
                     r"CPU\), so its Zenoh session lapsed; then subsystem S\d", stderr), stderr
    assert float(re.search(r"did not run for (\d+\.\d) s", stderr).group(1)) >= 20.0
