"""A run's signals as tables to take away: every output of every subsystem and the residual power and
energy of every bond, with units in the column names.

One table per communication grid: a table holds ``time [s]`` and every signal sampled at exactly its
rows, so no table has a hole (a multi-rate run gives several tables, not one table padded with NaN).
A subsystem's outputs sit on its own communication grid; a bond's residual power ``delta_p.<bond>
[W]`` and residual energy ``delta_e.<bond> [J]`` where both its sides communicate (paper 002 Eqs.
8–9). Output names are those the subsystems declare; a name that two subsystems declare (``energy``)
is prefixed with its subsystem (``S1.energy``).

Files (:func:`write_tables`): ``.csv`` (values written as Python writes a float: they read back bit for
bit), ``.npz`` (one float64 array per column) and ``.parquet`` (with pyarrow: ``zencosim[parquet]``).
A run with several grids writes one file per grid, named after the grid: ``out.csv`` becomes
``out.1ms.csv`` and ``out.2ms.csv``.
"""
from __future__ import annotations

import csv
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from zencosim.extras import require
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scheme.base import RunRecord

TIME_COLUMN = "time [s]"
FORMATS = (".csv", ".npz", ".parquet")


@dataclass(frozen=True)
class Signal:
    """One signal of a run at the points where it is sampled: ``values[i]`` at base step ``steps[i]``."""

    name: str  # "x2", "S1.energy", "delta_p.c1"
    unit: str  # SI
    source: str  # the subsystem that outputs it, or the bond it belongs to
    steps: np.ndarray  # (samples,) int64 base macro-steps
    values: np.ndarray  # (samples,) float64
    base_step_ns: int

    @property
    def time(self) -> np.ndarray:
        """Simulated time [s] of each sample."""
        return self.steps * self.base_step_ns / 1e9

    @property
    def column(self) -> str:
        return f"{self.name} [{self.unit}]"


@dataclass(frozen=True)
class Table:
    """The signals sampled on one communication grid of ``step_ns``; ``columns`` starts with ``time [s]``."""

    step_ns: int
    columns: dict[str, np.ndarray]

    @property
    def label(self) -> str:
        """The grid's step in the largest unit that makes it a whole number: ``1ms``, ``500us``, ``2s``."""
        for unit, scale in (("s", 10**9), ("ms", 10**6), ("us", 10**3)):
            if self.step_ns % scale == 0:
                return f"{self.step_ns // scale}{unit}"
        return f"{self.step_ns}ns"


def run_signals(plan: Plan, trajectories: list[np.ndarray], residual_power: np.ndarray,
                residual_energy: np.ndarray, last_step: int) -> dict[str, Signal]:
    """Every signal of a run up to base step ``last_step`` (the last committed one), by name: the outputs of
    each subsystem in scene and port order, then the residuals of each bond."""
    declared = Counter(port.name for sub in plan.subsystems for port in sub.outputs)
    base = plan.base_step_ns
    signals = {}
    for sub in plan.subsystems:
        steps = np.arange(0, last_step + 1, sub.ratio, dtype=np.int64)
        for j, port in enumerate(sub.outputs):
            name = port.name if declared[port.name] == 1 else f"{sub.name}.{port.name}"
            signals[name] = Signal(name, port.unit, sub.name, steps, trajectories[sub.index][:len(steps), j], base)
    for b, bond in enumerate(plan.bonds):
        period = math.lcm(plan.subsystems[bond.force_side].ratio, plan.subsystems[bond.motion_side].ratio)
        steps = np.arange(0, last_step + 1, period, dtype=np.int64)
        for prefix, unit, values in (("delta_p", "W", residual_power), ("delta_e", "J", residual_energy)):
            name = f"{prefix}.{bond.name}"
            signals[name] = Signal(name, unit, bond.name, steps, values[steps, b], base)
    return signals


def record_signals(record: RunRecord) -> dict[str, Signal]:
    """Every signal of a run's record (``run_signals``)."""
    return run_signals(record.plan, record.trajectories, record.residual_power, record.residual_energy,
                       record.last_step)


def tables(signals: dict[str, Signal]) -> list[Table]:
    """The signals grouped by the grid they are sampled on, finest grid first."""
    grids: dict[bytes, list[Signal]] = {}
    for signal in signals.values():
        grids.setdefault(signal.steps.tobytes(), []).append(signal)
    result = []
    for group in grids.values():
        first = group[0]
        step_ns = int(first.steps[1] - first.steps[0]) * first.base_step_ns if len(first.steps) > 1 else first.base_step_ns
        columns = {TIME_COLUMN: first.time, **{signal.column: signal.values for signal in group}}
        result.append(Table(step_ns, columns))
    return sorted(result, key=lambda table: table.step_ns)


def check_table_path(path: str | Path) -> Path:
    """``path`` once a table can be written there (known suffix, existing directory, the extra a format needs)."""
    path = check_output_file(path, "results file", FORMATS)
    if path.suffix.lower() == ".parquet":
        require("parquet", f"writing {path}")
    return path


def table_paths(path: Path, grids: list[Table]) -> list[Path]:
    """Where each table goes: ``path`` itself for a single grid, else ``<stem>.<grid>.<suffix>`` beside it."""
    if len(grids) == 1:
        return [path]
    return [path.with_name(f"{path.stem}.{table.label}{path.suffix}") for table in grids]


def write_tables(grids: list[Table], path: str | Path) -> list[Path]:
    """Write the tables to ``path`` (format by its suffix, see the module text); return the files written."""
    path = check_table_path(path)
    paths = table_paths(path, grids)
    for table, target in zip(grids, paths):
        suffix = target.suffix.lower()
        if suffix == ".csv":
            _write_csv(table, target)
        elif suffix == ".npz":
            np.savez(target, **table.columns)
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq
            pq.write_table(pa.table(table.columns), target)
    return paths


def _write_csv(table: Table, path: Path) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(table.columns)
        writer.writerows(np.column_stack(list(table.columns.values())).tolist())  # floats as repr: exact
