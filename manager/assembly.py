"""A run's objects from its scene — built the same way in every process that runs a replica of it.

The subsystems with everything attached to them (couplings, and the compensator the scene asks for),
the run plan, and the scheme generator with the correctors the scene asks for.
"""
from __future__ import annotations

import math
from contextlib import AbstractContextManager, nullcontext
from typing import Callable

from zencosim.manager.plan.attachments import build_subsystem, coupling_attachments
from zencosim.manager.plan.run_plan import Plan, compile_plan
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import SubsystemCalls
from zencosim.manager.scheme.correction import build_correctors
from zencosim.manager.scheme.energy_step import StepLaw, energy_controlled
from zencosim.manager.scheme.implicit import compile_joint, implicit
from zencosim.manager.scheme.jacobi import jacobi
from zencosim.manager.scheme.pacing import SPIN_ALONE_NS, Pacer, ThreadScheduling
from zencosim.manager.scheme.replica import Tap
from zencosim.manager.scheme.window import spill_for
from zencosim.manager.wire.status import StatusReport
from zencosim.subsystems.ports import Attachments
from zencosim.subsystems.subsystem import Subsystem


def attachments(scene: Scene) -> dict[str, Attachments]:
    """What every coupling, then the compensator the scene asks for, adds to every subsystem."""
    result = coupling_attachments(scene)
    if scene.manager.compensation == "eigenstructure":
        # imported here: the design needs scipy.optimize, which a subsystem process of any other scene need
        # not load (it starts in about half the time without it)
        from zencosim.manager.analysis.compensator import scene_compensator
        for sub, added in scene_compensator(scene).attachments.items():
            result[sub] = result[sub] + added
    return result


def build_subsystems(scene: Scene, constructing: Callable[[str], AbstractContextManager] = nullcontext
                     ) -> dict[str, Subsystem]:
    """Every subsystem of ``scene``, built; each construction inside ``constructing(name)`` (a watched run marks
    them: ``manager.bus.watchdog``)."""
    attached = attachments(scene)
    built = {}
    for name in scene.subsystems:
        with constructing(name):
            built[name] = build_subsystem(scene, name, attached[name])
    return built


def plan_scene(scene: Scene, constructing: Callable[[str], AbstractContextManager] = nullcontext
               ) -> tuple[Plan, dict]:
    """The run plan and the built subsystems (the manager builds them too, to know their ports); ``constructing``
    as in ``build_subsystems``."""
    subsystems = build_subsystems(scene, constructing)
    plan = compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})
    return plan, subsystems


def make_scheme(scene: Scene, plan: Plan, realtime: bool = False, start_ns: int | None = None,
                progress: Callable[[int], None] | None = None, status: StatusReport | None = None,
                spin_ns: int = SPIN_ALONE_NS, local: frozenset[int] | None = None, keep: bool | None = None,
                cpu: int | None = None, who: str = "zencosim", direct: SubsystemCalls | None = None,
                tap: Tap | None = None, follower: bool = False):
    """The scheme generator of a run, with the correctors the scene asks for; paced to deadlines
    ``start_ns + j * macro_step`` when ``realtime`` (``start_ns`` on this process's monotonic clock; None: the
    first step starts the clock); reporting its status after every macro-step with ``status`` (a
    recorded run); ``spin_ns``: see ``manager.scheme.pacing``; ``local``: the subsystems this process computes
    commands for (``manager.scheme.jacobi``; None: all; the implicit scheme always follows all); ``keep``: hold the
    run's arrays whole in memory (True), spill them to files as the run goes (False), or spill those of a
    long run only (None; ``manager.scheme.window.spill_for``); ``cpu``: the CPU the pacing thread keeps to when
    the scene sets ``manager.realtime_affinity`` (``who`` names the process in a warning when a real-time lever
    is refused); ``direct``: the subsystems of an in-process run, which the Jacobi scheme then calls itself
    (``manager.bus.inproc.DirectCalls``; the implicit scheme exchanges messages), handing ``tap`` (a recorded run's)
    the messages a replica would; ``follower``: its replica follows the run from the network, executing no command
    (the manager's over Zenoh: ``manager.scheme.jacobi``)."""
    levers = scene.manager
    scheduling = (ThreadScheduling(levers.realtime_priority, cpu if levers.realtime_affinity else None, who)
                  if levers.realtime_priority or levers.realtime_affinity else None)
    if scene.manager.step_control == "energy":
        if realtime:
            raise ValueError("a real-time run paces a fixed macro-step; manager.step_control = 'energy' varies it")
        law = StepLaw(scene.manager.energy_control, plan.base_step_ns, math.lcm(*(s.ratio for s in plan.subsystems)))
        return energy_controlled(plan, law, progress, status, spill_for(law.most_points(plan.n_ticks), keep),
                                 direct if tap is None and status is None else None)
    pacer = Pacer(plan.base_step_ns, start_ns, spin_ns, scheduling) if realtime else None
    spill = spill_for(plan.n_ticks, keep)
    if scene.manager.scheme == "implicit":
        return implicit(plan, compile_joint(scene, plan), scene.manager.implicit, pacer, progress, status, spill)
    return jacobi(plan, pacer, progress, build_correctors(plan, scene.manager.correction, local, spill), status, local,
                  spill, direct, tap, follower)


def process_scope(scene: Scene, plan: Plan, name: str) -> tuple[frozenset[int] | None, frozenset[str]]:
    """What the process of subsystem ``name`` computes and whom it exchanges with: its ``local`` set for
    ``make_scheme`` (its own subsystem; None under the implicit scheme, whose every process follows the
    whole joint, and with an energy-controlled step, which every bond sets) and the names of the processes it
    needs direct links to."""
    own = plan.by_name(name).index
    if scene.manager.scheme == "implicit" or scene.manager.step_control == "energy":
        return None, frozenset(s.name for s in plan.subsystems if s.name != name)
    return frozenset({own}), frozenset(plan.subsystems[i].name for i in plan.partners(own))
