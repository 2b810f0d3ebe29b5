"""One run of a scene: build, plan, drive the scheme on a bus, compare with the references, summarise."""
from __future__ import annotations

import time
from typing import Callable

from manager.build import monolithic_unavailable
from manager.jacobi import RunRecord
from manager.reference import analytic_reference, monolithic_reference, solve_ivp_reference
from manager.replica import Replica
from manager.scene import Scene
from manager.schemes import endpoints, make_scheme, plan_scene
from manager.summary import summarize
from manager.zenoh_bus import ZenohBus
from manager.zenoh_session import ZenohOptions

BUSES = ("inproc", "zenoh")


def execute(scene: Scene, bus: str = "inproc", realtime: bool | None = None,
            progress: Callable[[int], None] | None = None, zenoh_options: ZenohOptions = ZenohOptions(),
            listen: str | None = None, external: tuple[str, ...] = (),
            announce: Callable[[str], None] | None = None) -> tuple[RunRecord, float]:
    """Run the co-simulation; return the record and the wall-clock time [s] of the stepping loop."""
    if bus not in BUSES:
        raise ValueError(f"unknown bus {bus!r}; expected one of {', '.join(BUSES)}")
    realtime = scene.manager.realtime if realtime is None else realtime
    plan, subsystems = plan_scene(scene)
    if bus == "inproc":
        replica = Replica(make_scheme(scene, plan, realtime, None, progress), [s.name for s in plan.subsystems],
                          endpoints(plan, subsystems))
        start = time.perf_counter()
        record = replica.run()
        return record, time.perf_counter() - start
    with ZenohBus(scene, plan, zenoh_options, listen, external, announce=announce) as zbus:
        return zbus.drive(realtime, progress)


def references(scene: Scene) -> tuple[dict, str | None]:
    """The references the scene asks for, or why there are none."""
    if scene.outputs.reference == "none":
        return {}, None
    if scene.outputs.reference == "solve_ivp":
        return {"solve_ivp": solve_ivp_reference(scene)}, None
    reason = monolithic_unavailable(scene)
    if reason:
        return {}, f"no analytic reference: {reason}"
    return {"analytic": analytic_reference(scene), "monolithic": monolithic_reference(scene)}, None


def run_scene(scene: Scene, bus: str = "inproc", realtime: bool | None = None,
              progress: Callable[[int], None] | None = None, **bus_options) -> dict:
    """Run a scene and return its summary (see manager.summary)."""
    record, wall_s = execute(scene, bus, realtime, progress, **bus_options)
    refs, note = references(scene)
    return summarize(scene, record, bus, wall_s, refs, note)
