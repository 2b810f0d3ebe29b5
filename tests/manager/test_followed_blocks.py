"""The manager's replica over Zenoh taking whole macro-steps at a time (``manager.scheme.followed_blocks``): the same
record as the replica that takes reply after reply, bit for bit, however the replies are batched; the same failure
named; the same progress. And a subsystem process's lock step (``manager.scheme.lock_step``): the same replies as
its replica stepping through the scheme's exchanges."""
from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.assembly import build_subsystems, make_scheme, plan_scene
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.plan.run_plan import compile_plan
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.scheme.followed_blocks import Follow
from zencosim.manager.scheme.jacobi import jacobi
from zencosim.manager.scheme.replica import Replica
from zencosim.manager.wire.protocol import HEADER, Kind, encode, encode_error

# single-rate, zero-order inputs: the scenes whose manager's replica follows in blocks (two and five subsystems; a
# nonlinear one)
SCENES = {"two_mass_damped": ["manager.duration=1.1"], "mass_chain": ["manager.duration=0.1"],
          "double_oscillator": ["manager.duration=0.2"], "nonlinear_oscillator_case1": ["manager.duration=0.2"]}


def _published(scene_name: str) -> tuple:
    """The scene's plan and every reply of an in-process run through the messages, in the order published."""
    scene = load_scene(scene_name, SCENES[scene_name])
    subsystems = build_subsystems(scene)
    plan = compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})
    published = []
    Replica(jacobi(plan), [s.name for s in plan.subsystems], endpoints(plan, subsystems),
            publish=lambda name, reply: published.append((name, reply))).run()
    return plan, published


PUBLISHED = {}


def published(scene_name: str) -> tuple:
    if scene_name not in PUBLISHED:
        PUBLISHED[scene_name] = _published(scene_name)
    return PUBLISHED[scene_name]


def _follow(plan, replies, batches: list[int], follower: bool, progress=None, together: int = 1) -> Replica:
    """The manager's replica fed ``replies``: each subsystem's in batches of the sizes ``batches`` cycles through
    (a batch goes out when it is full, or at the end), in the order the subsystems published them, handed over
    ``together`` batches at a time (the batches a lagging follower finds waiting)."""
    manager = Replica(jacobi(plan, progress=progress, follower=follower), [s.name for s in plan.subsystems],
                      on_drop=lambda name, reason: pytest.fail(f"{name}'s reply dropped: {reason}"))
    manager.start()
    pending = {s.name: [] for s in plan.subsystems}
    sizes = {s.name: deque(batches) for s in plan.subsystems}
    ready = []
    for name, reply in replies:
        pending[name].append(reply)
        if len(pending[name]) >= sizes[name][0]:
            ready.append((name, pending[name]))
            pending[name] = []
            sizes[name].rotate(-1)
            if len(ready) == together:
                manager.deliver_batches(ready)
                ready = []
    manager.deliver_batches(ready + [(name, rest) for name, rest in pending.items()])
    return manager


def _same_record(ours, theirs) -> None:
    for a, b in zip(ours.trajectories, theirs.trajectories, strict=True):
        assert a.tobytes() == b.tobytes()
    assert ours.residual_power.tobytes() == theirs.residual_power.tobytes()
    assert ours.residual_energy.tobytes() == theirs.residual_energy.tobytes()
    assert len(ours.send_time_ns) == len(theirs.send_time_ns) == ours.plan.n_ticks


@settings(max_examples=12, deadline=None)
@given(st.sampled_from(sorted(SCENES)), st.lists(st.integers(1, 70), min_size=1, max_size=5), st.integers(1, 6))
def test_blocks_of_any_size_give_the_record_of_the_replica_that_takes_reply_after_reply(scene_name, batches, together):
    plan, replies = published(scene_name)
    generic = _follow(plan, replies, [1], follower=False)
    blocks = _follow(plan, replies, batches, follower=True, together=together)
    assert generic.finished and blocks.finished
    _same_record(blocks.result, generic.result)


def test_the_follower_asks_for_blocks_only_where_it_can_take_them():
    for name, overrides, expected in [("two_mass_damped", [], True), ("hydraulic_crane", [], False),  # multi-rate
                                      ("two_mass_damped", ["manager.extrapolation=1"], False),  # FOH inputs
                                      ("double_oscillator", [], True),
                                      ("double_oscillator", ["manager.correction.enabled=true"], False)]:
        scene = load_scene(name, ["manager.duration=0.05", *overrides])
        plan, _ = plan_scene(scene)
        scheme = make_scheme(scene, plan, follower=True)
        request = next(scheme)
        while not isinstance(request, Follow) and request.step == 0:  # the initialisation rounds, answered
            request = scheme.send({n: _initial(plan, n) for n in request.awaits})
        assert isinstance(request, Follow) == expected, (name, overrides)


def _initial(plan, name: str) -> bytes:
    return encode(Kind.OUTPUT, 0, 0, np.zeros(len(plan.by_name(name).outputs)))


@pytest.mark.parametrize("at", [1, 537, 1100])  # an ERROR in the first block, amid the run, at its last step
def test_an_error_reply_ends_the_run_with_the_failure_the_step_by_step_replica_names(at):
    plan, replies = published("two_mass_damped")
    replies = [(name, encode_error(at, at * plan.base_step_ns, "the model blew up", HEADER.unpack_from(reply)[6])
                if name == "S2" and HEADER.unpack_from(reply)[4] == at else reply) for name, reply in replies]
    failures = []
    for follower in (False, True):
        with pytest.raises(SubsystemFailure) as failure:
            _follow(plan, replies, [64], follower)
        failures.append(str(failure.value))
    assert failures[0] == failures[1] == f"subsystem S2: failed at step {at}: the model blew up"


def test_progress_is_reported_at_the_steps_the_step_by_step_replica_reports_it():
    plan, replies = published("two_mass_damped")
    reported = {False: [], True: []}
    for follower, steps in reported.items():
        _follow(plan, replies, [7, 64, 3], follower, steps.append)
    assert reported[True] == reported[False] == list(range(500, plan.n_ticks + 1, 500))


def _process(plan, name: str, replies, subsystems) -> tuple[Replica, list[bytes]]:
    """Subsystem ``name``'s process replica (``subsystems.process.host``), fed its sources' ``replies`` in order; it
    and what it published."""
    own = plan.by_name(name)
    tracked = [s.name for s in plan.subsystems if s.index in plan.tracked(frozenset({own.index}))]
    published = []
    replica = Replica(jacobi(plan, local=frozenset({own.index})), tracked, endpoints(plan, subsystems, [name]),
                      lambda _, reply: published.append(reply),
                      on_drop=lambda sender, reason: pytest.fail(f"{sender}'s reply dropped: {reason}"))
    replica.start()
    for sender, reply in replies:
        if sender != name and sender in tracked:
            replica.deliver(sender, reply)
    return replica, published


@pytest.mark.parametrize("scene_name", ["two_mass_damped", "mass_chain"])
def test_each_process_in_lock_step_publishes_the_replies_of_the_run_through_the_scheme(scene_name):
    plan, replies = published(scene_name)
    for s in plan.subsystems:
        scene = load_scene(scene_name, SCENES[scene_name])
        process, sent = _process(plan, s.name, replies, build_subsystems(scene))
        assert process.finished
        assert sent == [reply for name, reply in replies if name == s.name]


def test_a_process_in_lock_step_ends_with_its_source_failure_named():
    plan, replies = published("two_mass_damped")
    at = 537
    replies = [(name, encode_error(at, at * plan.base_step_ns, "the model blew up", HEADER.unpack_from(reply)[6])
                if name == "S1" and HEADER.unpack_from(reply)[4] == at else reply) for name, reply in replies]
    scene = load_scene("two_mass_damped", SCENES["two_mass_damped"])
    with pytest.raises(SubsystemFailure, match=f"^subsystem S1: failed at step {at}: the model blew up$"):
        _process(plan, "S2", replies, build_subsystems(scene))


def test_a_block_with_a_cut_reply_and_a_padded_one_is_not_taken_and_both_are_dropped():
    """One reply of S2 a float short and its next a float long (the block's bytes add up as if they were whole): the
    block goes back to the queues, the step-by-step replica drops both, takes the genuine ones that follow, and the
    record is the one of the replies as published."""
    plan, replies = published("two_mass_damped")
    s2 = [at for at, (name, _) in enumerate(replies) if name == "S2"]
    short, long_ = s2[10], s2[11]
    forged = list(replies)
    forged[short] = ("S2", replies[short][1][:-8])
    forged[long_] = ("S2", replies[long_][1] + replies[short][1][-8:])
    forged[long_ + 1:long_ + 1] = [replies[short], replies[long_]]  # the genuine ones, after the forged pair
    dropped = []
    manager = Replica(jacobi(plan, follower=True), [s.name for s in plan.subsystems],
                      on_drop=lambda name, reason: dropped.append(name))
    manager.start()
    manager.deliver_batches([(name, [reply]) for name, reply in forged])
    assert manager.finished and dropped == ["S2", "S2"]
    _same_record(manager.result, _follow(plan, replies, [1], follower=False).result)
