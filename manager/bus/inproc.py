"""The in-process bus: every subsystem in this process.

The Jacobi scheme calls the subsystems itself (:class:`DirectCalls`), handing each its input polynomial and
taking its outputs as arrays, with no decoding, CRC check or replica between them. The arithmetic is the
message path's — the same input polynomials (a zero-order one is the source's newest outputs, as the bytes a
command would copy), the same ``Subsystem.advance``, the same committed values — so the digest equals that of a
run through the messages and over Zenoh (tests/manager/test_direct.py compares every array of every bundled
scene). A recorded run's tap gets the commands and replies the scheme encodes for it, byte for byte and in the
order a replica would hand them over. The implicit scheme, which saves, restores and projects, exchanges its
messages through ``encode``/``decode`` and a replica of its scheme (``subsystems.process.endpoint``). A failing
model is named as its ERROR reply would name it (``failure_reason``), and a watched run
(``manager.bus.watchdog``) marks the calls into models that are not zencosim's own.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from zencosim.manager.bus.signals import InterruptWatch
from zencosim.manager.bus.watchdog import STEPPING, model_watch
from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.base import RunRecord, SubsystemFailure
from zencosim.manager.scheme.replica import Replica, Tap
from zencosim.manager.wire.text import printable
from zencosim.subsystems.models import MODELS
from zencosim.subsystems.process.endpoint import SubsystemEndpoint, failure_reason
from zencosim.subsystems.straight_line import StepText
from zencosim.subsystems.subsystem import Subsystem


class DirectCalls:
    """The subsystems of ``plan`` (built, ``subsystems`` by name), called by the scheme (``SubsystemCalls``)."""

    def __init__(self, plan: Plan, subsystems: dict[str, Subsystem]) -> None:
        self.subsystems = [subsystems[s.name] for s in plan.subsystems]
        self.advance = [subsystem.advance_values for subsystem in self.subsystems]
        self.base_step_ns = plan.base_step_ns
        self.comm_step_ns = [s.ratio * plan.base_step_ns for s in plan.subsystems]
        self.watch = model_watch()
        # in a watched run, the watch's number of each subsystem whose calls it marks (watched_models); else None
        marked = watched_models(subsystems) if self.watch.shared else set()
        self.marks = [self.watch.index(s.name) if s.name in marked else None for s in plan.subsystems]

    def initial(self, s: SubsystemPlan, w0: np.ndarray) -> np.ndarray:
        mark = self.marks[s.index]
        try:
            if mark is None:
                return self.subsystems[s.index].output_values(w0)
            with self.watch.marking(mark, STEPPING):
                return self.subsystems[s.index].output_values(w0)
        except (Exception, SystemExit, KeyboardInterrupt) as error:
            raise self.failure(s, 0, error) from None

    def step(self, s: SubsystemPlan, tick: int, coefficients: np.ndarray | list[float], span: int = 0
             ) -> list[float] | np.ndarray:
        # initial's body over advance_values, written out: the stepping loop's path, with no further call in between
        i = s.index
        t0_ns = tick * self.base_step_ns
        t1_ns = t0_ns + (span * self.base_step_ns if span else self.comm_step_ns[i])
        mark = self.marks[i]
        try:
            if mark is None:
                return self.advance[i](t0_ns, t1_ns, coefficients)
            with self.watch.marking(mark, STEPPING, t0_ns):
                return self.advance[i](t0_ns, t1_ns, coefficients)
        except (Exception, SystemExit, KeyboardInterrupt) as error:
            raise self.failure(s, tick + (span or s.ratio), error) from None

    def step_text(self, s: SubsystemPlan, prefix: str, start_ns: str) -> StepText | None:
        """``s``'s zero-order step as statements (``Subsystem.step_text``), or None; in a watched run, a model that is
        not zencosim's own marks its step as ``step`` does (``ModelWatch.marking_statements``; its native step, the
        register program's call of it: ``NativeStep.marks``)."""
        text = self.subsystems[s.index].step_text(self.comm_step_ns[s.index], prefix, start_ns)
        mark = self.marks[s.index]
        if text is None or mark is None:
            return text
        before, after = self.watch.marking_statements(mark, start_ns, f"{prefix}watched")
        native = None if text.native is None else replace(text.native, marks=self.watch.slots, mark=mark)
        return replace(text, statements=(*before, *text.statements, *after),
                       namespace={**text.namespace, f"{prefix}watched": self.watch.slots}, native=native)

    def state(self, s: SubsystemPlan) -> list[float]:
        return self.subsystems[s.index].z.tolist()

    def took_steps(self, s: SubsystemPlan, tick: int, z: list[float], w: list[float]) -> None:
        self.subsystems[s.index].took_steps(tick * self.base_step_ns, z, w)

    def failure(self, s: SubsystemPlan, due: int, error: BaseException) -> BaseException:
        """``s``'s failure as its ERROR reply would name it, or the user's interrupt as it was; no model's call is under
        way any more."""
        self.watch.clear()
        reason = failure_reason(error)
        return error if reason is None else SubsystemFailure(s.name, f"failed at step {due}: {printable(reason)}")


def watched_models(subsystems: dict[str, Subsystem]) -> set[str]:
    """The subsystems whose models a watched run marks: every one that is not one of zencosim's own models (an FMU,
    a Python class, an input table), which alone can end the process or hang in a step."""
    own = tuple(MODELS.values())
    return {name for name, subsystem in subsystems.items() if not isinstance(subsystem.model, own)}


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
        # a watched run marks the calls into models not zencosim's own (manager.bus.watchdog)
        local = model_watch().endpoints(endpoints(plan, subsystems), watched_models(subsystems))
        return Replica(scheme, [s.name for s in plan.subsystems], local, tap=tap).run()
