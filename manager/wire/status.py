"""The manager's status after every macro-step: a wire message (kind STATUS) of named float64 fields.

The field names are declared once, by :class:`StatusReport` (a recording stores them in its channel
metadata); a message carries only the values, in that order. Step ``k`` reports the macro-step that
ended at ``t_k``: the residual power and energy of every bond at ``t_k`` (NaN where a bond is not
evaluated at ``t_k``, multi-rate), and the wall-clock timing of that macro-step. Fields are added at
the end of the list; *measured* fields (wall-clock times) differ from run to run and are left out
when a recording is verified by re-running it.
"""
from __future__ import annotations

from dataclasses import dataclass

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.wire.protocol import Kind, floats_encoder


@dataclass(frozen=True)
class StatusField:
    name: str
    unit: str
    measured: bool = False  # a wall-clock measurement, not a result of the co-simulation


class StatusReport:
    """Encodes the status of a run with ``plan``'s bonds (paced to the wall clock when ``realtime``)."""

    def __init__(self, plan: Plan, realtime: bool) -> None:
        bonds = [b.name for b in plan.bonds]
        self.fields: tuple[StatusField, ...] = (
            *(StatusField(f"delta_p.{b}", "W") for b in bonds),  # residual power δP of bond b
            *(StatusField(f"delta_e.{b}", "J") for b in bonds),  # residual energy δE of bond b
            StatusField("wall_time", "s", measured=True),  # since step 0 was released, when this step completed
            StatusField("step_wall_time", "s", measured=True),  # from the release of the step to its completion
            *((StatusField("lateness", "s", measured=True),) if realtime else ()),  # release minus deadline
        )
        self._encode = floats_encoder(Kind.STATUS, len(self.fields))

    def encode(self, step: int, time_ns: int, residuals: list[float], start_ns: int, released_ns: int,
               completed_ns: int, lateness_ns: int | None) -> bytes:
        """The STATUS message of step ``step``: ``residuals`` are δP of every bond, then δE of every bond, as
        Python floats (the scheme's own, not a numpy row: this runs every step); times from
        ``time.perf_counter_ns``."""
        if lateness_ns is None:
            return self._encode(step, time_ns, 0, *residuals, (completed_ns - start_ns) * 1e-9,
                                (completed_ns - released_ns) * 1e-9)
        return self._encode(step, time_ns, 0, *residuals, (completed_ns - start_ns) * 1e-9,
                            (completed_ns - released_ns) * 1e-9, lateness_ns * 1e-9)
