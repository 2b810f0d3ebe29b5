"""Input values from a table: an external model's inputs that no coupling feeds, given over time.

A CSV file (``input_table = "inputs.csv"`` in the subsystem's table, ``zencosim run model.fmu --input
inputs.csv``) in the layout of the FMI cross-check rules that fmpy reads: a header line, the time [s] in
the first column, one column per input variable (named after it, SI values), one row per sample, times
not decreasing (a time given twice is a step). The values at time t are fmpy's: linear interpolation
between samples, the first and last values held outside them, the value after a step at its time
(``fmpy.simulation.Input.interpolate``), so that a run of one FMU takes the inputs ``fmpy.simulate_fmu``
would set.
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
    component's inputs; None with a problem when it cannot be used."""
    if not isinstance(value, str) or not value:
        problems.add(key, f"expected the path of a CSV file of input values, got {value!r}")
        return None
    path = (directory / value).resolve()
    try:
        from fmpy.util import read_csv
    except ImportError:
        problems.add(key, "reading an input table needs fmpy (pip install 'zencosim[fmu]')")
        return None
    try:
        data = read_csv(path)
    except OSError as error:
        problems.add(key, f"{path}: cannot read: {error.strerror or error}")
        return None
    except (ValueError, IndexError) as error:
        problems.add(key, f"{path}: expected a header line, then rows of numbers separated by commas ({error})")
        return None
    names = data.dtype.names or ()
    if len(names) < 2 or data.size < 1 or any(data.dtype[n].shape for n in names):
        problems.add(key, f"{path}: expected a time column and at least one input column of numbers, and a row")
        return None
    time = np.atleast_1d(data[names[0]]).astype(np.float64)
    values = np.array([np.atleast_1d(data[n]) for n in names[1:]], dtype=np.float64)
    before = len(problems)
    if not all(math.isfinite(v) for v in (*time, *values.ravel())):
        problems.add(key, f"{path}: expected finite numbers only")
    elif np.any(np.diff(time) < 0.0):
        problems.add(key, f"{path}: expected times that do not decrease (column {names[0]!r})")
    for name in names[1:]:
        variable = description.variables.get(name)
        if variable is None or variable.causality != "input":
            problems.add(key, f"{path}: column {name!r} is not a real input of the {description.kind}; expected "
                              f"one of {', '.join(description.inputs) or '(none)'}")
    if len(problems) != before:
        return None
    return InputTable(path, tuple(names[1:]), time, values)
