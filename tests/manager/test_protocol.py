"""The wire codec: exact float64 round trips, and clear errors for malformed or out-of-order messages."""
from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import alive, wait_for
from zencosim.manager.assembly import build_subsystems
from zencosim.manager.bus.children import cpu_time_s, exit_reason, process_state, start_child
from zencosim.manager.bus.dropped import DroppedMessages, checked, describe, merge
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.plan.run_plan import compile_plan
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.scheme.jacobi import jacobi
from zencosim.manager.scheme.replica import Replica
from zencosim.manager.wire.protocol import (
    HEADER,
    TABLED_BYTES,
    Kind,
    ProtocolError,
    command_ref,
    command_refs,
    decode,
    encode,
    encode_error,
)
from zencosim.manager.wire.text import printable
from zencosim.subsystems.process.endpoint import failure_reason


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=64), st.integers(0, 2 ** 40),
       st.integers(-2 ** 62, 2 ** 62))
def test_round_trip_is_exact_to_the_bit(values, step, time_ns):
    array = np.array(values, dtype=np.float64)
    message = decode(encode(Kind.OUTPUT, step, time_ns, array), "test")
    assert (message.kind, message.step, message.time_ns) == (Kind.OUTPUT, step, time_ns)
    assert message.values.tobytes() == array.tobytes()


@pytest.mark.parametrize("mangle,reason", [
    (lambda b: b[:10], "shorter than the 32-byte header"),
    (lambda b: b[:-1], "47 bytes, expected 48 for 2 values"),
    (lambda b: bytes([9]) + b[1:], "protocol version 9, expected 2"),
    (lambda b: b[:1] + bytes([99]) + b[2:], "unknown kind 99"),
])
def test_malformed_messages_are_rejected(mangle, reason):
    good = encode(Kind.OUTPUT, 1, 1000, np.array([1.0, 2.0]))
    with pytest.raises(ProtocolError, match=reason):
        decode(mangle(good), "subsystem S1")


def _endpoints(scene):
    subsystems = build_subsystems(scene)
    plan = compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})
    return plan, endpoints(plan, subsystems)


def _run(plan, local):
    return Replica(jacobi(plan), list(local), local).run()


def test_an_out_of_order_reply_is_rejected():
    plan, endpoints = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.01"]))
    real = endpoints["S2"].handle

    def stale(data):  # answers every step with the step number of the previous one
        reply = bytearray(real(data))
        version, kind, rows, count, step, time_ns, ref = HEADER.unpack_from(reply)
        if kind == Kind.OUTPUT and step > 1:
            HEADER.pack_into(reply, 0, version, kind, rows, count, step - 1, time_ns, ref)
        return bytes(reply)

    endpoints["S2"].handle = stale
    with pytest.raises(ProtocolError, match="subsystem S2: expected OUTPUT for step 2, got OUTPUT for step 1"):
        _run(plan, endpoints)


def test_a_failing_subsystem_is_named_with_its_reason():
    plan, endpoints = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.01"]))
    endpoints["S1"].subsystem.t_ns = 123  # the next STEP starts at a time S1 is not at
    with pytest.raises(SubsystemFailure, match="subsystem S1: failed at step 0: ProtocolError: subsystem S1: INIT at t = 0 ns, but it is at 123 ns"):
        _run(plan, endpoints)


def test_save_and_restore_over_the_protocol_repeat_a_step_bit_for_bit():
    _, endpoints = _endpoints(load_scene("two_mass_damped"))
    s1 = endpoints["S1"]
    inputs = np.array([[0.01, -2.0]])
    step = lambda k: s1.handle(encode(Kind.STEP, k, k * 1_000_000, inputs, rows=1))  # noqa: E731
    step(0)
    assert decode(s1.handle(encode(Kind.SAVE, 1, 1_000_000)), "S1").kind == Kind.ACK
    first = step(1)
    assert decode(s1.handle(encode(Kind.RESTORE, 1, 1_000_000)), "S1").kind == Kind.ACK
    assert step(1) == first
    error = decode(s1.handle(encode(Kind.RESTORE, 7, 0)), "S1")
    assert error.kind == Kind.ERROR and "no state saved at step 7" in error.text()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1e3, 1e3)), min_size=1,
                max_size=20), st.sampled_from(["two_mass_damped", "hydraulic_crane"]), st.integers(0, 3))
def test_a_zero_order_step_taken_as_floats_answers_the_bytes_the_decoded_one_does(inputs, name, mangle):
    """A STEP with one row of inputs is read as floats, not an array (``SubsystemEndpoint._zero_order_step``): the
    same reply, byte for byte, as the decoded command's (``_dispatch``), for a linear and a nonlinear subsystem, values
    of every kind, and commands that are not such a STEP (cut, of two rows, of the wrong count) answered alike."""
    scene = load_scene(name, ["manager.duration=0.05"])
    (_, ours), (_, theirs) = (_endpoints(scene) for _ in range(2))
    target = next(iter(ours))
    n = len(ours[target].subsystem.inputs)
    comm_step_ns = ours[target].ratio * ours[target].base_step_ns
    for k, (first, rest) in enumerate(inputs):
        values = np.array([[first] + [rest] * (n - 1)])
        command = encode(Kind.STEP, k, k * comm_step_ns, values, rows=1)
        if k == len(inputs) - 1:  # the last: perhaps not a zero-order STEP at all
            command = [command, command[:-8], encode(Kind.STEP, k, k * comm_step_ns, np.vstack([values, values]),
                                                     rows=2), encode(Kind.STEP, k, k * comm_step_ns, values[:, :-1],
                                                                     rows=1)][mangle]
        with np.errstate(all="ignore"):
            assert ours[target].handle(command) == _decoded_reply(theirs[target], command)


def _decoded_reply(endpoint, command: bytes) -> bytes:
    """The reply to ``command`` through the decoded message (``SubsystemEndpoint._dispatch``), a failure answered as
    ``handle`` answers it."""
    step, time_ns, ref = -1, -1, command_ref(command)
    try:
        message = decode(command, "manager")
        step, time_ns = message.step, message.time_ns
        return endpoint._dispatch(message, ref)
    except Exception as error:  # noqa: BLE001 (every failure is the ERROR reply's)
        return encode_error(step, time_ns, failure_reason(error), ref)


def test_the_manager_drops_every_reply_of_a_subsystem_whose_replica_executed_another_command():
    plan, local = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.01"]))
    names = [s.name for s in plan.subsystems]
    published = []  # what a subsystem process would publish
    executor = Replica(jacobi(plan), names, local, publish=lambda name, reply: published.append((name, reply)))
    dropped = []
    follower = Replica(jacobi(load_plan_with_other_extrapolation()), names,  # the manager's copy
                       on_drop=lambda name, reason: dropped.append((name, reason)))
    executor.start()
    follower.start()
    for name, reply in published:
        follower.deliver(name, reply)
    assert follower.steps_done == 2 and not follower.finished  # both initialisation rounds agree; the STEPs do not
    assert {name for name, _ in dropped} == {"S1", "S2"}
    assert all("answers another command than this replica computed" in reason for _, reason in dropped)


def _published(plan, local) -> list[tuple[str, bytes]]:
    """Every reply of an in-process run, in the order the subsystems would publish them."""
    published = []
    Replica(jacobi(plan), [s.name for s in plan.subsystems], local,
            publish=lambda name, reply: published.append((name, reply))).run()
    return published


@pytest.mark.parametrize("follower", [False, True])  # the manager's replica step by step; in blocks (followed_blocks)
def test_stray_garbled_and_replayed_replies_are_dropped_and_the_run_is_bit_identical(follower):
    plan, local = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.05"]))
    names = [s.name for s in plan.subsystems]
    genuine = _published(plan, local)
    reference = Replica(jacobi(plan), names, _endpoints(load_scene("two_mass_damped", ["manager.duration=0.05"]))[1]).run()
    strays = {10: ("S1", b"\xee" * 100), 20: ("S2", genuine[3][1]), 30: ("S1", genuine[30][1][:-1]),
              40: ("S2", encode(Kind.STEP, 7, 0, np.ones(1), rows=1))}  # garbage, a replay, cut short, no reply

    def follow(replica: Replica) -> None:
        replica.start()
        for at, (name, reply) in enumerate(genuine):
            if at in strays:
                replica.deliver(*strays[at])
            if name in replica.replies and name not in replica.local:
                replica.deliver(name, reply)

    dropped = []
    manager = Replica(jacobi(plan, follower=follower), names, on_drop=lambda name, reason: dropped.append((name, reason)))
    follow(manager)  # checks every reply's reference
    assert manager.finished and len(dropped) == len(strays)
    assert [r for _, r in dropped][1].startswith("answers another command")
    for ours, theirs in zip(manager.result.trajectories, reference.trajectories):
        assert ours.tobytes() == theirs.tobytes()

    dropped.clear()  # S2's process: it does not compute S1's commands, so it checks S1's replies by their step
    s2_plan, s2_local = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.05"]))
    own = frozenset({s2_plan.by_name("S2").index})
    published = []  # what S2's process publishes: its replies, which its record does not keep (manager.scheme.lock_step)
    s2 = Replica(jacobi(s2_plan, local=own), names, {"S2": s2_local["S2"]}, lambda *sent: published.append(sent),
                 on_drop=lambda name, reason: dropped.append((name, reason)))
    strays = {at: stray for at, stray in strays.items() if stray[0] == "S1"} | {50: ("S1", genuine[2][1])}
    follow(s2)
    assert s2.finished and len(dropped) == len(strays)
    assert "the scheme awaits step" in dropped[-1][1]
    assert published == [(name, reply) for name, reply in genuine if name == "S2"]


def test_a_replica_looks_at_each_reply_from_the_network_once(tmp_path):
    """A star of 9: the manager's replica awaits 9 replies a step; each is screened once (on arrival, or when a
    request awaits it), not once per reply that arrives after it (a step's screening grew with n² before)."""
    from zencosim.scenes.topologies import mass_star

    path = tmp_path / "star9.toml"
    path.write_text(mass_star(9, 0.02))
    plan, local = _endpoints(load_scene(str(path)))
    genuine = _published(plan, local)
    manager = Replica(jacobi(plan), [s.name for s in plan.subsystems], on_drop=lambda name, reason: None)
    looked = []
    fault = manager.fault
    manager.fault = lambda name, reply: looked.append(name) or fault(name, reply)
    manager.start()
    for name, reply in genuine:
        manager.deliver(name, reply)
    assert manager.finished and len(looked) == len(genuine)


def load_plan_with_other_extrapolation():
    # the same scene but first-order extrapolation: from the second step on, the commands differ
    plan, _ = _endpoints(load_scene("two_mass_damped", ["manager.duration=0.01", "manager.extrapolation=1"]))
    return plan


def test_text_from_the_network_reaches_a_terminal_without_its_control_characters():
    reason = "bad\x1b]0;title\x07\x1b[2J\r\u202eend\ttab\nnext\x9b"
    message = decode(encode_error(3, 0, reason), "subsystem S1")
    assert message.text() == "bad\\x1b]0;title\\x07\\x1b[2J\\r\\u202eend\ttab\nnext\\x9b"
    assert printable("plain text, ünïcode: 1 µs") == "plain text, ünïcode: 1 µs"


def test_a_stopped_process_is_named_frozen_and_a_running_one_is_not():
    sleeper = subprocess.Popen(["sleep", "60"])
    try:
        wait_for(lambda: process_state(sleeper.pid) is None, 10, "the sleeper to sleep")
        os.kill(sleeper.pid, signal.SIGSTOP)
        # until the stop takes effect the sleeper may pass through another state (D while a page of `sleep` is
        # read in on a busy machine, as CI once saw): wait for the named state, fail if it never comes
        wait_for(lambda: (process_state(sleeper.pid) or "").startswith("is frozen (process stopped, state T"), 10,
                 "the sleeper to be named frozen")
        os.kill(sleeper.pid, signal.SIGCONT)
        wait_for(lambda: process_state(sleeper.pid) is None, 10, "the sleeper to go on")
    finally:
        sleeper.kill()
        sleeper.wait()
    assert exit_reason(sleeper.returncode) == "killed by SIGKILL" and exit_reason(3) == "exited with code 3"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="vfork")
def test_starting_a_child_leaves_the_memory_of_this_process_private():
    """start_child spawns without a preexec_fn, so subprocess uses vfork: the pages this process writes
    afterwards do not fault one by one, as each did after a fork (copy-on-write; ~7 400 faults in the first
    steps of a recorded in-process run). The child still ends with its parent (test_buses, test_recorded_runs)."""
    pages = 8192
    memory = bytearray(pages * 4096)
    memory[::4096] = b"\1" * pages  # every page mapped before the child starts
    child = start_child("zencosim", ["--version"], stdout=subprocess.DEVNULL)
    assert child.wait(60) == 0
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    memory[::4096] = b"\2" * pages
    # a fork faults once per page (8 192); without one only what else runs here faults (a few)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before < pages // 10


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG")
def test_a_child_whose_parent_died_before_it_started_ends_at_once():
    """The parent-death signal is asked for by the child itself (end_with_parent): a parent gone before
    that has already been replaced by another, and the child ends instead of running on, an orphan."""
    parent = subprocess.run([sys.executable, "-c", "from zencosim.manager.bus.children import start_child\n"
                             "child = start_child('zencosim', ['run', 'two_mass_damped', '--quiet', '--set', "
                             "'manager.duration=100000'], stdout=-3, stderr=-3)\nprint(child.pid)"],
                            capture_output=True, text=True, timeout=60, check=True)
    orphan = int(parent.stdout)
    try:  # a run of 10^8 steps; ended, it is gone (or a zombie its new parent has not reaped)
        wait_for(lambda: not alive(orphan), 60, "the orphaned run to end")
    finally:
        if alive(orphan):
            os.kill(orphan, signal.SIGKILL)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
def test_the_cpu_time_of_a_process_is_read_from_proc_and_a_gone_one_has_none():
    """What start-up counts as progress (manager.bus.zenoh_bus): a busy child's CPU time grows past 0.1 s; a
    sleeping one's stays near 0; a process that is gone reads as 0 (no error)."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    sleeper = subprocess.Popen(["sleep", "60"])
    try:
        assert wait_for(lambda: cpu_time_s(busy.pid) >= 0.1, 60, "the busy child to use 0.1 s of CPU")
        assert cpu_time_s(sleeper.pid) < 0.1
    finally:
        for child in (busy, sleeper):
            child.kill()
            child.wait()
    assert cpu_time_s(busy.pid) == 0.0 and process_state(busy.pid) is None


def test_the_drops_of_every_process_are_merged_per_key_and_said_in_one_sentence():
    manager, s2 = DroppedMessages(), DroppedMessages()
    for _ in range(3):
        manager.add("zencosim/r/S1/log", "answers another command")
    s2.add("zencosim/r/S1/y", "protocol version 238, expected 2", "zenoh id abc entity 1")
    from_network = {"zencosim/r/S1/log": {"count": 2, "reason": "x"}, "bad": {"count": "2"}, "worse": 7}
    merged = merge({"manager": manager.report(), "S2": s2.report(), "S1": checked(from_network)})
    assert merged["zencosim/r/S1/log"] == {"count": 5, "reason": "answers another command", "publisher": None,
                                           "seen_by": ["manager", "S1"]}
    assert set(merged) == {"zencosim/r/S1/log", "zencosim/r/S1/y"} and checked([1]) == {}
    assert describe(merged) == ("5 dropped on zencosim/r/S1/log by manager, S1 (first: answers another command); "
                                "1 dropped on zencosim/r/S1/y by S2 from zenoh id abc entity 1 "
                                "(first: protocol version 238, expected 2)")


@settings(max_examples=60, deadline=None)
@given(st.integers(1, TABLED_BYTES + 8), st.integers(0, 40), st.integers(0, 2**32 - 1))
def test_command_refs_are_zlibs_crc32_of_each_command(length, count, seed):
    """The CRC-32 of a block of commands from tables (an affine map over bytes) against zlib's on each: generated
    lengths on both sides of the tables' limit, random bytes and rows of only 0x00 or 0xFF."""
    rng = np.random.default_rng(seed)
    commands = rng.integers(0, 256, (count, length), dtype=np.uint8)
    commands[::3] = 0
    commands[1::5] = 0xFF
    refs = command_refs(commands)
    assert refs.dtype == np.uint32
    assert refs.tolist() == [zlib.crc32(row.tobytes()) for row in commands] == [command_ref(bytes(row))
                                                                                   for row in commands]
