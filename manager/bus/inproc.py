"""The in-process bus: one replica of the scheme holds every subsystem and executes every command itself.

Commands and replies still pass through the wire protocol's ``encode``/``decode``
(``subsystems.process.endpoint``), so a codec bug shows on both buses.
"""
from __future__ import annotations

from zencosim.manager.bus.signals import InterruptWatch
from zencosim.manager.bus.watchdog import model_watch
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.scheme.replica import Replica, Tap
from zencosim.subsystems.process.endpoint import SubsystemEndpoint


def endpoints(plan: Plan, subsystems: dict, names: list[str] | None = None) -> dict[str, SubsystemEndpoint]:
    """Protocol endpoints of the built subsystems (all of them, or ``names``)."""
    return {s.name: SubsystemEndpoint(subsystems[s.name], s.ratio, plan.base_step_ns)
            for s in plan.subsystems if names is None or s.name in names}


def run_in_process(scheme, plan: Plan, subsystems: dict, tap: Tap | None = None
                   ) -> RunRecord:
    """Run ``scheme`` to its end with every subsystem of ``plan`` in this process; ``tap`` sees every
    message (``manager.scheme.replica``). A model that raises KeyboardInterrupt itself, with no SIGINT or SIGTERM
    received, has failed (``subsystems.process.endpoint``): the watch tells the two apart."""
    with InterruptWatch():
        local = model_watch().endpoints(endpoints(plan, subsystems))  # marked in a watched run (manager.bus.watchdog)
        return Replica(scheme, [s.name for s in plan.subsystems], local, tap=tap).run()
