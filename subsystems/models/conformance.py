"""One conformance check for every model (STYLE: Gymnasium's check_env): built-in, FMU or a user's class.

:func:`check_subsystem` drives a subsystem with seeded random input polynomials and reports what it
finds wrong, each as a sentence that names the port, step or method:

* every port has a coherent SI unit and a unique name (an FMU's units with a factor and offset are
  converted at its boundary; a variable without a unit is named, and checked with its value as it is);
* the outputs are finite;
* two instances give bit-identical outputs (no hidden randomness or shared state);
* an output that does not declare direct feedthrough does not change when only the inputs change;
* saving, stepping, restoring and stepping again repeats the outputs bit for bit (where the model can
  save its state).

``zencosim check-model`` runs it over a user's class or an FMU with a port for each of its variables
(:func:`check_component`); the test suite runs it over every subsystem of every bundled scene, and over
the models given with ``pytest --model REF``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.models import model_traits
from zencosim.subsystems.models.external.fmu import FmuError, FmuFileError
from zencosim.subsystems.models.external.model import (
    ExternalSettings,
    ExternalSpec,
    FmuModel,
    apply_units,
    python_model,
    read_start,
)
from zencosim.subsystems.models.external.python_model import ModelClassError
from zencosim.subsystems.params import Problems
from zencosim.subsystems.subsystem import Subsystem
from zencosim.subsystems.units import UnitError, exponents

STEPS = 20  # communication steps each instance is driven
SCALES = np.array([[1.0], [10.0], [100.0]])  # of the random constant, linear and quadratic coefficients


def _drive(subsystem: Subsystem, rng: np.random.Generator, start: int, steps: int, comm_step_ns: int,
           rows: int, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The outputs under seeded random input polynomials; an input with a declared range (``bounds``: lowest and
    highest value of each input) gets a constant inside it, as a component may refuse anything else."""
    outputs = []
    bounded = np.zeros(0, dtype=bool) if bounds is None else np.isfinite(bounds[0]) | np.isfinite(bounds[1])
    if bounded.any():  # a range open on one side: 1 wide
        low, high = bounds[0][bounded], bounds[1][bounded]
        low, high = np.where(np.isfinite(low), low, high - 1.0), np.where(np.isfinite(high), high, low + 1.0)
    for k in range(start, start + steps):
        coefficients = rng.normal(size=(rows, len(subsystem.inputs))) * SCALES[:rows]
        if bounded.any():
            coefficients[0, bounded] = low + rng.uniform(size=low.size) * (high - low)
            coefficients[1:, bounded] = 0.0
        outputs.append(subsystem.advance(k * comm_step_ns, (k + 1) * comm_step_ns, InputPolynomial(coefficients)))
    return np.array(outputs).reshape(steps, len(subsystem.outputs))


def check_subsystem(make: Callable[[], Subsystem], comm_step_ns: int, can_save_state: bool = True,
                    seed: int = 7, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> list[str]:
    """What is wrong with the subsystems ``make`` builds (empty: nothing), advanced over steps of
    ``comm_step_ns`` (``bounds``: the declared range of each input, lowest and highest values)."""
    problems = []
    first, second = make(), make()
    ports = first.inputs + first.outputs
    for port in ports:
        try:
            exponents(port.unit)
        except UnitError as error:
            problems.append(f"port {port.name}: {error}")
    names = [p.name for p in ports]
    problems += [f"port name {n!r} is used twice" for n in sorted({n for n in names if names.count(n) > 1})]
    try:
        a = _drive(first, np.random.default_rng(seed), 0, STEPS, comm_step_ns, 3, bounds)
        b = _drive(second, np.random.default_rng(seed), 0, STEPS, comm_step_ns, 3, bounds)
    except Exception as error:  # the model's own failure is what the check reports
        return problems + [f"advancing it failed: {type(error).__name__}: {error}"]
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        step, output = bad[0]
        return problems + [f"output {first.outputs[output].name} is {a[step, output]} at step {step + 1}"]
    if a.tobytes() != b.tobytes():
        problems.append("two instances given the same inputs give different outputs")
    problems += _feedthrough_problems(first, np.random.default_rng(seed + 1), bounds)
    if can_save_state:
        saved = first.save()
        ahead = _drive(first, np.random.default_rng(seed + 2), STEPS, 5, comm_step_ns, 1, bounds)
        first.restore(saved)
        if isinstance(saved.model, (bytes, type(None))) and first.save() != saved:
            problems.append("restore() does not return the saved state")
        again = _drive(first, np.random.default_rng(seed + 2), STEPS, 5, comm_step_ns, 1, bounds)
        if ahead.tobytes() != again.tobytes():
            problems.append("stepping again after restore() gives different outputs: the state is not all saved")
    return problems


def _feedthrough_problems(subsystem: Subsystem, rng: np.random.Generator,
                          bounds: tuple[np.ndarray, np.ndarray] | None = None) -> list[str]:
    """Outputs that change with the inputs at one instant but do not declare direct feedthrough (the energy,
    which no coupling routes, is exempt); an input with a declared range keeps a value inside it."""
    if not subsystem.inputs:
        return []
    here, there = rng.normal(size=len(subsystem.inputs)), rng.normal(size=len(subsystem.inputs)) * 10.0
    if bounds is not None:
        low, high = bounds
        here, there = (np.where(np.isfinite(low) | np.isfinite(high), np.clip(w, low, high), w) for w in (here, there))
    here, there = subsystem.output_values(here), subsystem.output_values(there)
    return [f"output {port.name} changes with the inputs at the same instant but does not declare feedthrough"
            for j, port in enumerate(subsystem.outputs)
            if not port.feedthrough and port.quantity != "energy" and here[j] != there[j]]


class UnusableModel(ValueError):
    """A reference ``check-model`` cannot check at all: no such file, not an FMU, a class it cannot find."""


def check_component(reference: str, start: dict[str, float], micro_step_ns: int = 1_000_000,
                    units: dict[str, str] | None = None) -> list[str]:
    """``zencosim check-model``: the conformance of a user's class (``module:Class`` or a registered name) or
    of an FMU (a path ending in ``.fmu``), with a port for each of its variables: the problems it has. The
    declarations come first; a variable without a unit zencosim can read is named (``units``, variable ->
    SI unit, gives it as a scene's ``units`` table does) and the check goes on with its value as it is;
    any other declaration problem ends the check. :class:`UnusableModel` when there is nothing to check."""
    is_fmu = reference.endswith(".fmu")
    try:
        model = FmuModel if is_fmu else python_model(reference)
    except ModelClassError as error:
        raise UnusableModel(str(error)) from None
    try:
        description, source = model.describe(ExternalSettings(fmu=reference if is_fmu else None), Path.cwd())
    except FmuFileError as error:
        raise UnusableModel(str(error)) from None
    except (FmuError, ModelClassError) as error:
        return [str(error)]
    problems = Problems()
    description = apply_units(units or None, description, "--unit", problems)
    values = read_start(start, description, "--start", problems)
    if problems:
        return [str(p).replace(".", " ", 1) for p in problems]  # --unit fc: …
    found = [f"{v.causality} {name}: {v.unit_problem}; its values are passed on as they are (declare its SI unit: "
             f"--unit {name}=UNIT here, units = {{ {name} = \"UNIT\" }} in a scene)"
             for name, v in description.variables.items()
             if v.causality in ("input", "output") and v.exponents is None and not v.discrete]
    spec = ExternalSpec(model.name, description, source, values, None, {})
    integrator = INTEGRATORS[model_traits(model, spec).default_integrator]

    def make() -> Subsystem:
        return Subsystem(reference, model(spec, expose_all=True), integrator, micro_step_ns)

    inputs = [description.variables[name] for name in description.inputs]  # in the order of the ports
    bounds = (np.array([v.minimum for v in inputs]), np.array([v.maximum for v in inputs]))
    try:
        return found + check_subsystem(make, micro_step_ns, description.can_save_state, bounds=bounds)
    except Exception as error:  # instantiating it failed: the user's constructor, the FMU's initialisation
        return found + [f"building it failed: {type(error).__name__}: {error}"]
