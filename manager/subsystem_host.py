"""A subsystem process: one subsystem of a scene, answering the manager over Zenoh.

Started by ``zencosim run --bus zenoh`` for every subsystem, or by hand on another host with
``zencosim subsystem SCENE NAME --connect tcp/HOST:PORT``. Commands are handled in the Zenoh
subscriber callback (one command at a time, in order) and answered at once, so no thread hand-off
sits on the critical path. The process ends on STOP, on SIGINT/SIGTERM, or when the manager's
liveliness token disappears.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time

import zenoh

from manager.build import build_subsystem
from manager.endpoint import SubsystemEndpoint
from manager.scene import Scene
from manager.zenoh_session import ZenohOptions, coupling_publisher, key, peer_config


class HostError(RuntimeError):
    """The subsystem process could not join a run."""


def describe(scene: Scene, name: str, subsystem) -> bytes:
    """What the manager checks before a run: same scene, same ports."""
    return json.dumps({
        "subsystem": name,
        "scene_digest": scene.digest,
        "inputs": [[p.name, p.unit] for p in subsystem.inputs],
        "outputs": [[p.name, p.unit] for p in subsystem.outputs],
        "pid": os.getpid(),
    }).encode()


def find_run(session: zenoh.Session, scene: Scene, name: str, wait_s: float) -> str:
    """The id of the one run that waits for subsystem ``name`` of this scene."""
    deadline = time.monotonic() + wait_s
    while True:
        candidates = []
        for reply in session.get(f"zencosim/*/manager/run", timeout=1.0):
            if reply.ok is None:
                continue
            info = json.loads(reply.ok.payload.to_bytes())
            if info.get("scene_digest") == scene.digest and name in info.get("waiting_for", []):
                candidates.append(info["run_id"])
        if len(candidates) == 1:
            return candidates[0]
        if len(candidates) > 1:
            raise HostError(f"several runs wait for {name} of scene {scene.name}: {', '.join(candidates)}; "
                            "choose one with --run-id")
        if time.monotonic() > deadline:
            raise HostError(f"no run of scene {scene.name} (digest {scene.digest[:12]}) waits for subsystem {name}; "
                            "is the manager started with the same scene and --set options?")
        time.sleep(0.2)


def serve(scene: Scene, name: str, connect: list[str], run_id: str | None, options: ZenohOptions,
          wait_s: float = 30.0) -> int:
    """Serve subsystem ``name`` until the run ends; return the process exit code."""
    if name not in scene.subsystems:
        raise HostError(f"scene {scene.name} has no subsystem {name!r}; expected one of {', '.join(scene.subsystems)}")
    subsystem = build_subsystem(scene, name)
    endpoint = SubsystemEndpoint(subsystem, scene.subsystems[name].settings.comm_ratio, scene.manager.macro_step_ns)
    finished = threading.Event()
    reason: list[str] = []

    def stop(why: str) -> None:
        reason.append(why)
        finished.set()

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda s, _f: stop(f"signal {signal.Signals(s).name}"))

    with zenoh.open(peer_config(connect=connect, options=options)) as session:
        if run_id is None:
            run_id = find_run(session, scene, name, wait_s)
        replies = coupling_publisher(session, key(run_id, name, "y"))

        def on_command(sample: zenoh.Sample) -> None:
            replies.put(endpoint.handle(sample.payload.to_bytes()))
            if endpoint.stopped:
                stop("stopped by the manager")

        def on_manager(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE:
                stop("the manager is gone")

        manager_seen = threading.Event()
        commands = session.declare_subscriber(key(run_id, name, "u"), on_command)
        description = describe(scene, name, subsystem)
        control = session.declare_queryable(key(run_id, name, "ctl"),
                                            lambda query: query.reply(key(run_id, name, "ctl"), description))
        watch = session.liveliness().declare_subscriber(
            key(run_id, "manager", "alive"),
            lambda sample: manager_seen.set() if sample.kind == zenoh.SampleKind.PUT else on_manager(sample),
            history=True)
        token = session.liveliness().declare_token(key(run_id, name, "alive"))
        if not manager_seen.wait(wait_s):
            stop(f"no manager of run {run_id} within {wait_s:g} s")
        finished.wait()
        token.undeclare()
        for entity in (watch, control, commands, replies):
            entity.undeclare()
    print(f"subsystem {name}: {reason[0]}", file=sys.stderr)
    return 0 if endpoint.stopped else 1
