"""The manager's status after every macro-step: a wire message (kind STATUS) of named float64 fields.

The field names are declared once, by :class:`StatusReport` (a recording stores them in its channel
metadata); a message carries only the values, in that order. Step ``k`` reports the macro-step that
ended at ``t_k``: the residual power and energy of every bond at ``t_k`` (NaN where a bond is not
evaluated at ``t_k``, multi-rate), and the wall-clock timing of that macro-step. Fields are added at
the end of the list; *measured* fields (wall-clock times) differ from run to run and are left out
when a recording is verified by re-running it.

The stepping loop does not encode the messages: as a scheme ends a step it only logs the step's figures
(``log_residuals``, ``log_times``: two list extensions; a generated loop logs a block of steps' arrays at a
time, ``log_steps``), and whoever taps the run takes the messages in step order (:meth:`StatusReport.take`),
encoded many steps at once with numpy when a batch is handed over — a recording's cost on the stepping loop
(docs/recording.md, Overhead).
"""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.wire.protocol import HEADER_DTYPE, VERSION, Kind

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
        self._blocks: list[tuple[np.ndarray, np.ndarray]] = []  # or (residuals, times) rows, a block at a time
        self._start_ns: int | None = None  # the release of step 0: the first step logged was released then
        self._table = np.dtype([("header", HEADER_DTYPE), ("values", "<f8", (len(self.fields),))])  # a message
        self.size = self._table.itemsize  # [bytes] of a message

    def log_steps(self, residuals: np.ndarray, steps: np.ndarray, released: np.ndarray, completed: np.ndarray) -> None:
        """Steps logged a block at a time, the values ``log_residuals`` and ``log_times`` log one by one (a generated
        loop's: ``manager.scheme.compiled``; a run logs one way or the other): per step its row of ``residuals`` (δP
        then δE of every bond), its number, its release and completion times [ns, perf_counter_ns]; no lateness (it
        is not paced). The arrays are kept as they are (not copied)."""
        self._blocks.append((residuals, np.column_stack((steps, released, completed, np.zeros_like(steps)))))

    @property
    def logged(self) -> int:
        """Steps logged and not yet taken."""
        return len(self._times) // TIMES + sum(len(times) for _, times in self._blocks)

    def take(self, count: int) -> Statuses:
        """The STATUS messages of the oldest ``count`` steps logged (they leave the log). The values are those the
        scheme computed, bit for bit; a time in seconds is its integer nanoseconds times 1e-9, as Python's."""
        count = min(count, self.logged)
        n_times, n_residuals = TIMES * count, self.n_residuals * count
        if self._blocks:  # logged a block at a time: the oldest rows, the rest kept as one block
            residual_rows = np.concatenate([rows for rows, _ in self._blocks])
            time_rows = np.concatenate([rows for _, rows in self._blocks])
            residuals, times = residual_rows[:count].ravel(), time_rows[:count]
            self._blocks = [(residual_rows[count:], time_rows[count:])] if count < len(time_rows) else []
        else:  # through struct, which converts a Python int or float in a fraction of numpy's time for a list of them
            times = np.frombuffer(struct.pack(f"<{n_times}q", *self._times[:n_times]), dtype=np.int64).reshape(
                count, TIMES)
            residuals = np.frombuffer(struct.pack(f"<{n_residuals}d", *self._residuals[:n_residuals]), dtype=np.float64)
            del self._times[:n_times], self._residuals[:n_residuals]
        if count == 0:
            return Statuses(b"", times[:, 0], times[:, 2])
        if self._start_ns is None:
            self._start_ns = int(times[0, 1])
        steps, released, completed = times[:, 0], times[:, 1], times[:, 2]
        table = np.zeros(count, dtype=self._table)
        header = table["header"]
        header["version"], header["kind"], header["count"] = VERSION, Kind.STATUS, len(self.fields)
        header["step"], header["time_ns"] = steps, steps * self.base_step_ns
        values, n = table["values"], self.n_residuals
        values[:, :n] = residuals.reshape(count, n)
        values[:, n] = (completed - self._start_ns) * 1e-9
        values[:, n + 1] = (completed - released) * 1e-9
        if self.realtime:
            values[:, n + 2] = times[:, 3] * 1e-9
        return Statuses(table.tobytes(), steps, completed + (time.time_ns() - time.perf_counter_ns()))
