"""The subsystem processes of a Zenoh run without Zenoh: their replicas in one thread, each reply handed to the others.

Each process of a Zenoh run runs a replica of the scheme for its own subsystem (``subsystems.process.host``): it
takes its sources' replies, computes its command, steps its subsystem and publishes the reply. Here every
process's replica runs in this thread and a published reply is delivered to the other replicas at once, in the
order published, so that what the processes compute per step besides Zenoh (publishing, callbacks, threads) can
be counted (bench_instructions.py --replicas).
"""
from __future__ import annotations

from collections import deque

from zencosim.manager.assembly import make_scheme, plan_scene, process_scope
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.replica import Replica


def replicas_in_lock_step(scene: Scene) -> list[tuple[str, bytes]]:
    """Run ``scene`` with one replica per subsystem, as its process runs it, to the end; every reply published, in
    the order published (``(subsystem, reply)``)."""
    replicas: dict[str, Replica] = {}
    published: deque[tuple[str, bytes]] = deque()
    for name in scene.subsystems:
        plan, subsystems = plan_scene(scene)
        scope, _ = process_scope(scene, plan, name)
        tracked = [plan.subsystems[i].name for i in sorted(plan.tracked(scope))]
        replicas[name] = Replica(make_scheme(scene, plan, local=scope), tracked, endpoints(plan, subsystems, [name]),
                                 lambda sender, reply: published.append((sender, reply)), on_drop=_dropped)
    # who takes each subsystem's replies: the processes that track it (subscribed to its key, as over Zenoh)
    takers = {sender: [replica for name, replica in replicas.items() if name != sender and sender in replica.replies]
              for sender in replicas}
    for replica in replicas.values():
        replica.start()
    replies = []
    while published:
        sender, reply = published.popleft()
        replies.append((sender, reply))
        for replica in takers[sender]:
            replica.deliver(sender, reply)
    waiting = {name: replica.waiting_for() for name, replica in replicas.items() if not replica.finished}
    if waiting:
        raise RuntimeError(f"replicas still waiting: {waiting}")
    return replies


def _dropped(sender: str, reason: str) -> None:
    raise RuntimeError(f"a reply of {sender} dropped: {reason}")
