"""Build a run's scheme from its scene — the same way in every process that runs a replica of it."""
from __future__ import annotations

from typing import Callable

from manager.build import build_subsystems
from manager.correction import build_correctors
from manager.endpoint import SubsystemEndpoint
from manager.implicit import compile_joint, implicit
from manager.jacobi import jacobi
from manager.pacing import SPIN_ALONE_NS, Pacer
from manager.plan import Plan, compile_plan
from manager.scene import Scene
from manager.status import StatusReport


def plan_scene(scene: Scene) -> tuple[Plan, dict]:
    """The run plan and the built subsystems (the manager builds them too, to know their ports)."""
    subsystems = build_subsystems(scene)
    plan = compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})
    return plan, subsystems


def make_scheme(scene: Scene, plan: Plan, realtime: bool = False, start_ns: int | None = None,
                progress: Callable[[int], None] | None = None, status: StatusReport | None = None,
                spin_ns: int = SPIN_ALONE_NS):
    """The scheme generator of a run, with the correctors the scene asks for; paced to deadlines
    ``start_ns + j * macro_step`` when ``realtime`` (``start_ns`` on this process's monotonic clock; None: the
    first step starts the clock); reporting its status after every macro-step with ``status`` (a
    recorded run); ``spin_ns``: see ``manager.pacing``."""
    pacer = Pacer(plan.base_step_ns, plan.n_ticks, start_ns, spin_ns) if realtime else None
    if scene.manager.scheme == "implicit":
        return implicit(plan, compile_joint(scene, plan), scene.manager.implicit, pacer, progress, status)
    return jacobi(plan, pacer, progress, build_correctors(plan, scene.manager.correction), status)


def endpoints(plan: Plan, subsystems: dict, names: list[str] | None = None) -> dict[str, SubsystemEndpoint]:
    """Protocol endpoints of the built subsystems (all of them, or ``names``)."""
    return {s.name: SubsystemEndpoint(subsystems[s.name], s.ratio, plan.base_step_ns)
            for s in plan.subsystems if names is None or s.name in names}
