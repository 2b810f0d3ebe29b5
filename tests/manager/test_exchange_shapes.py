"""``Exchange.shape`` keeps its promise (``manager.scheme.base``): within a run, one shape stands for one set of
names — the subsystems the request before awaited, whether a status is reported, the subsystems sent to (in
order) and those awaited. A tap derives channel indices from the names once per shape (``recordings.recorder``),
so a shape that stood for two sets of names would put messages on the wrong channels of a recording.

Checked on the jacobi replica of every subsystem (in process) and on the replica of each subsystem's own process
(``local``: it sends only its own commands and awaits only what it tracks), single- and multi-rate."""
from __future__ import annotations

from collections import defaultdict, deque

import pytest

from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import run_in_process
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.jacobi import jacobi
from zencosim.manager.scheme.lock_step import LockStep
from zencosim.manager.wire.status import StatusReport

SCENES = [("two_mass_damped", ["manager.duration=0.05"]),  # period 1
          ("hydraulic_crane", ["manager.duration=0.1"]),  # multi-rate: ratios 40 and 1, a period of 40 steps
          ("mass_chain", ["manager.duration=0.02"])]  # five subsystems


class _Names:
    """A tap that notes, per exchange, its shape and the names it stands for; and the replies, per subsystem."""

    def __init__(self) -> None:
        self.exchanges: list[tuple[int | None, tuple]] = []
        self.replies: dict[str, list[bytes]] = defaultdict(list)
        self.awaited: tuple[str, ...] = ()

    def exchange(self, replies, request) -> None:
        for name, reply in (replies or {}).items():
            self.replies[name].append(reply)
        if request is not None:
            self.exchanges.append((request.shape, (self.awaited, request.status is not None, tuple(request.sends),
                                                   request.awaits)))
            self.awaited = request.awaits


def _assert_one_set_of_names_per_shape(exchanges: list[tuple[int | None, tuple]], shaped: int) -> None:
    names_of = defaultdict(set)
    for shape, names in exchanges:
        if shape is not None:
            names_of[shape].add(names)
    assert {shape: len(names) for shape, names in names_of.items()} == dict.fromkeys(names_of, 1)
    assert sum(shape is not None for shape, _ in exchanges) == shaped


@pytest.mark.parametrize("scene_name, overrides", SCENES)
def test_a_shape_stands_for_one_set_of_names_on_every_replica(scene_name, overrides):
    scene = load_scene(scene_name, overrides)
    plan, subsystems = plan_scene(scene)
    full = _Names()
    run_in_process(make_scheme(scene, plan, status=StatusReport(plan, False)), plan, subsystems, full)
    _assert_one_set_of_names_per_shape(full.exchanges, plan.n_ticks - 1)  # every step after the first has one

    for own in plan.subsystems:  # each subsystem's process: fed the replies it awaits, in order, from the run above
        replies = {name: deque(taken) for name, taken in full.replies.items()}
        scheme = jacobi(plan, local=frozenset({own.index}))
        local, request, lock_stepped = _Names(), next(scheme), False
        try:
            while True:
                if isinstance(request, LockStep):  # every step in one request (a single-rate ZOH process): none to tap
                    assert (request.first, request.end) == (0, plan.n_ticks)
                    lock_stepped = True
                    request = scheme.send(None)
                    continue
                local.exchange(None, request)
                request = scheme.send({name: replies[name].popleft() for name in request.awaits})
        except StopIteration:
            pass
        _assert_one_set_of_names_per_shape(local.exchanges, 0 if lock_stepped else plan.n_ticks - 1)
        assert lock_stepped == (scene_name != "hydraulic_crane")  # single-rate zero-order: every step in one request
        assert {sends for _, (_, _, sends, _) in local.exchanges} <= {(own.name,), ()}
