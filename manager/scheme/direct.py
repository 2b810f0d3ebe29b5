"""The in-process bus's fast path: the scheme calls the subsystems itself, with arrays, not commands and replies.

A run in process that nothing taps (no recording, no live view) needs no messages: the Jacobi scheme
(``manager.scheme.jacobi``) then hands each subsystem its input polynomial and takes its outputs as arrays, with
no encoding, no CRC, no decoding and no replica between them. The arithmetic is the same — the same input
polynomials (a zero-order one is the source's newest outputs, as the bytes a command would copy), the same
``Subsystem.advance``, the same committed values — so the run's digest equals that of the run through the wire
protocol and over Zenoh (tests/manager/test_direct.py compares every array of every bundled scene). A failing
model is named as its ERROR reply would name it (``subsystems.process.endpoint.failure_reason``), and a watched run
(``manager.bus.watchdog``) marks every call.
"""
from __future__ import annotations

import numpy as np

from zencosim.manager.bus.watchdog import model_watch
from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.wire.text import printable
from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.process.endpoint import failure_reason
from zencosim.subsystems.subsystem import Subsystem


class DirectCalls:
    """The subsystems of ``plan`` (built, ``subsystems`` by name), called by the scheme."""

    def __init__(self, plan: Plan, subsystems: dict[str, Subsystem]) -> None:
        self.subsystems = [subsystems[s.name] for s in plan.subsystems]
        self.base_step_ns = plan.base_step_ns
        watch = model_watch()
        self.watch = watch if watch.shared else None
        self.watched = [watch.index(s.name) for s in plan.subsystems] if watch.shared else []

    def initial(self, s: SubsystemPlan, w0: np.ndarray) -> np.ndarray:
        """``s``'s outputs at t_0 with the input values ``w0`` (an INIT command's)."""
        return self._call(s, 0, 0, self.subsystems[s.index].output_values, w0)

    def step(self, s: SubsystemPlan, tick: int, coefficients: np.ndarray) -> np.ndarray:
        """``s``'s outputs at the end of its step from base step ``tick`` over the input polynomial ``coefficients``
        (a STEP command's)."""
        t0_ns = tick * self.base_step_ns
        return self._call(s, tick + s.ratio, t0_ns, self.subsystems[s.index].advance, t0_ns,
                          t0_ns + s.ratio * self.base_step_ns, InputPolynomial(coefficients))

    def _call(self, s: SubsystemPlan, due: int, t_ns: int, function, *arguments) -> np.ndarray:
        watch = self.watch
        try:
            if watch is None:
                return function(*arguments)
            watch.calling(self.watched[s.index], t_ns)
            try:
                return function(*arguments)
            finally:
                watch.returned()
        except (Exception, SystemExit, KeyboardInterrupt) as error:
            reason = failure_reason(error)
            if reason is None:
                raise
            raise SubsystemFailure(s.name, f"failed at step {due}: {printable(reason)}") from None
