"""Input values from a table: an external model's inputs that no coupling feeds, given over time.

A CSV file (``input_table = "inputs.csv"`` in the subsystem's table, ``zencosim run model.fmu --input
inputs.csv``) in the layout of the FMI cross-check rules that fmpy reads: a header line, the time [s] in
the first column, one column per input variable (named after it, SI values), one row per sample (at least
two), times not decreasing (a time given twice is a step). What is not such a table (a file that is not a
regular one, such as /dev/zero; a row of too few values; a word where a number belongs) is refused naming
the line and the column. The values at time t are fmpy's: linear interpolation between samples, the first
and last values held outside them, the value after a step at its time (``fmpy.simulation.Input.interpolate``),
so that a run of one FMU takes the inputs ``fmpy.simulate_fmu`` would set.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from zencosim.subsystems.models.external.component import ComponentDescription
from zencosim.subsystems.params import Problems


@dataclass(frozen=True, eq=False)
class InputTable:
    """Samples of input variables over time."""

    path: Path
    variables: tuple[str, ...]  # the component's input variables, in column order
    time: np.ndarray  # (n_samples,) [s]
    values: np.ndarray  # (n_variables, n_samples), SI

    def at(self, t: float) -> np.ndarray:
        """The input values at time ``t`` [s] (fmpy's interpolation, the value after a step)."""
        from fmpy.simulation import Input
        values, _ = Input.interpolate(t, self.time, self.values, after_event=True)
        return np.asarray(values, dtype=np.float64)


def read_input_table(value: object, description: ComponentDescription, directory: Path, key: str,
                     problems: Problems) -> InputTable | None:
    """The table the ``input_table`` key names (a path relative to the scene file), checked against the
    component's inputs; None with a problem (naming the file, and the line and column where it is) when it cannot
    be used."""
    if not isinstance(value, str) or not value:
        problems.add(key, f"expected the path of a CSV file of input values, got {value!r}")
        return None
    path = (directory / value).resolve()
    try:
        import fmpy.simulation  # noqa: F401 (InputTable.at interpolates as fmpy does)
    except ImportError:
        problems.add(key, "reading an input table needs fmpy (pip install 'zencosim[fmu]')")
        return None
    try:
        names, rows = _read_csv(path, description)
    except TableError as error:
        problems.add(key, f"{path}: {error}")
        return None
    time, values = rows[:, 0].copy(), np.ascontiguousarray(rows[:, 1:].T)
    unknown = [name for name in names[1:] if getattr(description.variables.get(name), "causality", None) != "input"]
    if unknown:
        problems.add(key, f"{path}: column {unknown[0]!r} is not a real input of the {description.kind}; expected "
                          f"one of {', '.join(description.inputs) or '(none)'}")
        return None
    return InputTable(path, tuple(names[1:]), time, values)


class TableError(ValueError):
    """Why a file is no table of input values (where in it, and what was expected)."""


LAYOUT = "a header line (the time, then one name per input variable), then rows of numbers, separated by commas"


def _read_csv(path: Path, description: ComponentDescription) -> tuple[list[str], np.ndarray]:
    """The column names and the rows (n_rows, n_columns) of the CSV file at ``path``, in the layout fmpy's
    ``read_csv`` reads (the FMI cross-check rules); raises :class:`TableError`."""
    if not path.is_file():  # a device (/dev/zero), a pipe or a folder: reading it would not end, or fail
        raise TableError("no such file" if not path.exists() else "not a regular file; expected a CSV file")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise TableError(f"cannot read: {error.strerror or error}") from None
    except UnicodeDecodeError:
        raise TableError(f"not text (UTF-8); expected {LAYOUT}") from None
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise TableError(f"empty; expected {LAYOUT}")
    (header_number, header), rows = lines[0], lines[1:]
    names = [name.strip().strip('"') for name in header.split(",")]
    if len(names) < 2 or not all(names) or len(set(names)) != len(names):
        raise TableError(f"line {header_number}: expected the names of the time column and of at least one input "
                         f"variable, each once, got {header.strip()!r}")
    if names[0] != "time" and ("time" in names or names[0] in description.variables):
        raise TableError(f"line {header_number}: the time must come first, got column {names[0]!r} first")
    if len(rows) < 2:
        raise TableError(f"{len(rows)} row(s) of values; expected at least two (the values between samples are "
                         "interpolated, as fmpy does; a constant input is one value at two times)")
    table = np.empty((len(rows), len(names)))
    for row, (number, line) in enumerate(rows):
        fields = line.split(",")
        if len(fields) != len(names):
            raise TableError(f"line {number}: {len(fields)} value(s), expected {len(names)} (one per column: "
                             f"{', '.join(names)})")
        for column, (name, field) in enumerate(zip(names, fields)):
            try:
                table[row, column] = float(field)
            except ValueError:
                raise TableError(f"line {number}, column {name!r}: expected a number, got {field.strip()!r}") from None
            if not math.isfinite(table[row, column]):
                raise TableError(f"line {number}, column {name!r}: expected a finite number, got {field.strip()!r}")
    back = np.flatnonzero(np.diff(table[:, 0]) < 0.0)
    if back.size:
        number, earlier = rows[back[0] + 1][0], rows[back[0]][0]
        later, before = float(table[back[0] + 1, 0]), float(table[back[0], 0])
        raise TableError(f"line {number}: time {later!r} s is before the {before!r} s of line {earlier}; expected "
                         f"times that do not decrease (column {names[0]!r})")
    return names, table
