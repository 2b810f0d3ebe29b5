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
import zipfile
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from zencosim.extras import require
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scheme.base import RunRecord, grid_ticks
from zencosim.manager.scheme.window import BLOCK_ROWS, read_rows

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


def _columns(plan: Plan, trajectories: list[np.ndarray], residual_power: np.ndarray, residual_energy: np.ndarray,
             last_step: int, point_ticks: np.ndarray | None = None) -> dict[str, tuple]:
    """Every signal of a run up to base step ``last_step`` by name, as ``(unit, source, every, count, values)``:
    a sample every ``every`` base steps, ``count`` samples, ``values`` a view of the run's arrays; with
    ``point_ticks`` (an energy-controlled run, ``RunRecord.point_ticks``) a sample every ``every`` of its points,
    up to its last."""
    declared = Counter(port.name for sub in plan.subsystems for port in sub.outputs)
    last = last_step if point_ticks is None else len(point_ticks) - 1  # the last point, in base steps or points
    columns = {}
    for sub in plan.subsystems:
        count = last // sub.ratio + 1
        for j, port in enumerate(sub.outputs):
            name = port.name if declared[port.name] == 1 else f"{sub.name}.{port.name}"
            columns[name] = (port.unit, sub.name, sub.ratio, count, trajectories[sub.index][:count, j])
    for b, bond in enumerate(plan.bonds):
        period = math.lcm(plan.subsystems[bond.force_side].ratio, plan.subsystems[bond.motion_side].ratio)
        for prefix, unit, values in (("delta_p", "W", residual_power), ("delta_e", "J", residual_energy)):
            columns[f"{prefix}.{bond.name}"] = (unit, bond.name, period, last // period + 1,
                                                values[:last + 1:period, b])
    return columns


class RunSignals(Mapping):
    """The signals of a run by name (``run_signals``), each made when it is asked for: its values are views of
    the run's arrays (a long run's read from its files as they are used, ``manager.scheme.window``), its
    steps made once per grid."""

    def __init__(self, columns: dict[str, tuple], base_step_ns: int, point_ticks: np.ndarray | None = None) -> None:
        self._columns, self._base, self._points = columns, base_step_ns, point_ticks
        self._steps: dict[tuple[int, int], np.ndarray] = {}

    def __getitem__(self, name: str) -> Signal:
        unit, source, every, count, values = self._columns[name]
        steps = self._steps.get((every, count))
        if steps is None:
            steps = self._steps[every, count] = grid_ticks(self._points, every, 0, count)
        return Signal(name, unit, source, steps, values, self._base)

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        return len(self._columns)


def run_signals(plan: Plan, trajectories: list[np.ndarray], residual_power: np.ndarray,
                residual_energy: np.ndarray, last_step: int, point_ticks: np.ndarray | None = None) -> RunSignals:
    """Every signal of a run up to base step ``last_step`` (the last committed one), by name: the outputs of
    each subsystem in scene and port order, then the residuals of each bond; ``point_ticks`` as ``_columns``."""
    return RunSignals(_columns(plan, trajectories, residual_power, residual_energy, last_step, point_ticks),
                      plan.base_step_ns, point_ticks)


def record_signals(record: RunRecord) -> RunSignals:
    """Every signal of a run's record (``run_signals``)."""
    return run_signals(record.plan, record.trajectories, record.residual_power, record.residual_energy,
                       record.last_step, record.point_ticks)


class GridTime:
    """The ``time [s]`` column of a grid, made block by block as it is read (``read_rows``): what
    ``Signal.time`` gives, ``steps * base_step_ns / 1e9`` — a sample every ``every`` base steps, or every ``every``
    of the points at the base steps ``point_ticks``."""

    def __init__(self, every: int, count: int, base_step_ns: int, point_ticks: np.ndarray | None = None) -> None:
        self.every, self.count, self.base_step_ns, self.point_ticks = every, count, base_step_ns, point_ticks

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, rows: slice) -> np.ndarray:
        start, stop, _ = rows.indices(self.count)
        return grid_ticks(self.point_ticks, self.every, start, stop) * self.base_step_ns / 1e9


def record_tables(record: RunRecord) -> list[Table]:
    """The tables of a run's record (as ``tables(record_signals(record))``) without reading its arrays: columns
    are views of them and the time column a :class:`GridTime`, so that ``write_tables`` writes a long run
    block by block."""
    plan = record.plan
    grids: dict[tuple[int, int], tuple[int, int, dict]] = {}
    columns = _columns(plan, record.trajectories, record.residual_power, record.residual_energy, record.last_step,
                       record.point_ticks)
    for name, (unit, _, every, count, values) in columns.items():
        grid = grids.setdefault((every if count > 1 else 0, count), (every, count, {}))
        grid[2][f"{name} [{unit}]"] = values
    result = [Table(every * plan.base_step_ns if count > 1 else plan.base_step_ns,
                    {TIME_COLUMN: GridTime(every, count, plan.base_step_ns, record.point_ticks), **columns})
              for every, count, columns in grids.values()]
    return sorted(result, key=lambda table: table.step_ns)


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
    """Write the tables to ``path`` (format by its suffix, see the module text), block by block of
    ``BLOCK_ROWS`` rows; return the files written."""
    path = check_table_path(path)
    paths = table_paths(path, grids)
    for table, target in zip(grids, paths):
        suffix = target.suffix.lower()
        writer = _write_csv if suffix == ".csv" else _write_npz if suffix == ".npz" else _write_parquet
        writer(table, target)
    return paths


def _blocks(table: Table) -> Iterator[list[np.ndarray]]:
    """The table's columns, ``BLOCK_ROWS`` rows at a time."""
    rows = len(next(iter(table.columns.values())))
    for start in range(0, rows, BLOCK_ROWS):
        yield [read_rows(column, start, min(start + BLOCK_ROWS, rows)) for column in table.columns.values()]


def _write_csv(table: Table, path: Path) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(table.columns)
        for block in _blocks(table):
            writer.writerows(np.column_stack(block).tolist())  # floats as repr: exact


def _write_npz(table: Table, path: Path) -> None:
    """What ``np.savez`` writes (one ``.npy`` per column, uncompressed), each column written in blocks."""
    rows = len(next(iter(table.columns.values())))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
        for j, name in enumerate(table.columns):
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(member, {"descr": np.dtype("<f8").str, "fortran_order": False,
                                                              "shape": (rows,)})
                for start in range(0, rows, BLOCK_ROWS):
                    column = read_rows(table.columns[name], start, min(start + BLOCK_ROWS, rows))
                    member.write(np.ascontiguousarray(column, dtype="<f8").tobytes())


def _write_parquet(table: Table, path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq
    writer = None
    try:
        for block in _blocks(table):
            part = pa.table(dict(zip(table.columns, block)))
            if writer is None:
                writer = pq.ParquetWriter(path, part.schema)
            writer.write_table(part)
    finally:
        if writer is not None:
            writer.close()
