"""The manager's status after every macro-step: a wire message (kind STATUS) of named float64 fields.

The field names are declared once, by :class:`StatusReport` (a recording stores them in its channel
metadata); a message carries only the values, in that order. Step ``k`` reports the macro-step that
ended at ``t_k``: the residual power and energy of every bond at ``t_k`` (NaN where a bond is not
evaluated at ``t_k``, multi-rate), and the wall-clock timing of that macro-step. Fields are added at
the end of the list; *measured* fields (wall-clock times) differ from run to run and are left out
when a recording is verified by re-running it.

The stepping loop does not encode the messages: as a scheme ends a step it only logs the step's figures
(``log_residuals``, ``log_times``: two list extensions), and whoever taps the run takes the messages in step
order (:meth:`StatusReport.take`), encoded many steps at once with numpy (:func:`status_messages`) when a batch
is handed over — a recording's cost on the stepping loop (docs/recording.md, Overhead). A generated loop's tap
hands over its rows instead, from which the recorder's processes build the same messages
(``recordings.rows_frame``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.wire.arrays import float64s, int64s
from zencosim.manager.wire.protocol import VERSION, Kind, message_dtype

TIMES = 4  # what a scheme logs per step in ``log_times``: (step, released, completed [ns, perf_counter_ns], lateness [ns])


class Statuses(NamedTuple):
    """STATUS messages taken from a log (:meth:`StatusReport.take`)."""

    messages: bytes  # one after the other, each ``StatusReport.size`` bytes
    steps: np.ndarray  # the step of each
    stamps: np.ndarray  # the wall-clock time [ns, time.time_ns] at which each step completed


@dataclass(frozen=True)
class StatusField:
    name: str
    unit: str
    measured: bool = False  # a wall-clock measurement, not a result of the co-simulation


class StatusReport:
    """The status of a run with ``plan``'s bonds (paced to the wall clock when ``realtime``): its fields, the log
    its scheme fills step by step, and the messages taken from that log (see the module text)."""

    def __init__(self, plan: Plan, realtime: bool) -> None:
        bonds = [b.name for b in plan.bonds]
        self.fields: tuple[StatusField, ...] = (
            *(StatusField(f"delta_p.{b}", "W") for b in bonds),  # residual power δP of bond b
            *(StatusField(f"delta_e.{b}", "J") for b in bonds),  # residual energy δE of bond b
            StatusField("wall_time", "s", measured=True),  # since step 0 was released, when this step completed
            StatusField("step_wall_time", "s", measured=True),  # from the release of the step to its completion
            *((StatusField("lateness", "s", measured=True),) if realtime else ()),  # release minus deadline
        )
        self.realtime = realtime
        self.base_step_ns = plan.base_step_ns
        self.n_residuals = 2 * len(bonds)
        # the log: per step, δP of every bond then δE of every bond (Python floats, the scheme's own), and TIMES ints
        self._residuals: list[float] = []
        self._times: list[int] = []
        self.log_residuals = self._residuals.extend
        self.log_times = self._times.extend
        self._start_ns: int | None = None  # the release of step 0: the first step logged was released then
        self.size = message_dtype(len(self.fields)).itemsize  # [bytes] of a message

    def log(self) -> tuple[int | None, list[float], list[int]]:
        """The log as it stands, nothing taken: the release of step 0 once a take found it, and the residuals and times
        not taken — a recorder's process takes their messages from a copy (:meth:`from_log`)."""
        return self._start_ns, self._residuals, self._times

    @classmethod
    def from_log(cls, n_residuals: int, base_step_ns: int, log: tuple[int | None, list[float], list[int]]
                 ) -> StatusReport:
        """A report of a run that is not paced whose :meth:`log` was ``log``, with ``n_residuals`` residuals per step:
        its :meth:`take` gives the messages the run's own would have given."""
        report = cls.__new__(cls)
        report.realtime, report.base_step_ns, report.n_residuals = False, base_step_ns, n_residuals
        report._start_ns, report._residuals, report._times = log[0], list(log[1]), list(log[2])
        return report

    @property
    def logged(self) -> int:
        """Steps logged and not yet taken."""
        return len(self._times) // TIMES

    def take(self, count: int) -> Statuses:
        """The STATUS messages of the oldest ``count`` steps logged (they leave the log). The values are those the
        scheme computed, bit for bit; a time in seconds is its integer nanoseconds times 1e-9, as Python's."""
        count = min(count, self.logged)
        n_times, n_residuals = TIMES * count, self.n_residuals * count
        times = int64s(self._times[:n_times]).reshape(count, TIMES)
        residuals = float64s(self._residuals[:n_residuals])
        del self._times[:n_times], self._residuals[:n_residuals]
        if count == 0:
            return Statuses(b"", times[:, 0], times[:, 2])
        if self._start_ns is None:
            self._start_ns = int(times[0, 1])
        steps, completed = times[:, 0], times[:, 2]
        messages = status_messages(residuals.reshape(count, self.n_residuals), steps, times[:, 1], completed,
                                   times[:, 3] if self.realtime else None, self._start_ns, self.base_step_ns)
        return Statuses(messages.tobytes(), steps, completed + (time.time_ns() - time.perf_counter_ns()))


def status_messages(residuals: np.ndarray, steps: np.ndarray, released: np.ndarray, completed: np.ndarray,
                    lateness: np.ndarray | None, start_ns: int, base_step_ns: int) -> np.ndarray:
    """The STATUS messages of ``steps`` (one row of bytes each), as :class:`StatusReport` declares their fields: each
    step's ``residuals`` (δP then δE of every bond), its wall time since the release of step 0 (``start_ns``) and its
    own, from its release to its completion [ns, perf_counter_ns → s: the integer nanoseconds times 1e-9, as
    Python's], and with ``lateness`` [ns] (a paced run) that too."""
    count, n = residuals.shape
    table = np.zeros(count, dtype=message_dtype(n + 2 + (lateness is not None)))
    header = table["header"]
    header["version"], header["kind"], header["count"] = VERSION, Kind.STATUS, table["values"].shape[1]
    header["step"], header["time_ns"] = steps, steps * base_step_ns
    values = table["values"]
    values[:, :n] = residuals
    values[:, n] = (completed - start_ns) * 1e-9
    values[:, n + 1] = (completed - released) * 1e-9
    if lateness is not None:
        values[:, n + 2] = lateness * 1e-9
    return table.view(np.uint8).reshape(count, table.dtype.itemsize)
