"""A user's Python model as a component (docs/models.md): a class that states its inputs, outputs and
parameters with SI units and gives its state derivative; zencosim's integrator advances its state.

The class is found by ``"package.module:ClassName"`` (the working directory searched after the installed
packages) or by the name a package registers in the entry-point group ``zencosim.models``.
:func:`describe_python` checks what can be checked without running it (attributes, methods, units) and
reports every problem at once.
"""
from __future__ import annotations

import importlib
import os
import sys
from importlib.metadata import entry_points

import numpy as np

from zencosim.subsystems.models.external.component import ComponentDescription, Variable
from zencosim.subsystems.units import UnitError, exponents

ENTRY_POINTS = "zencosim.models"


class ModelClassError(ValueError):
    """A model class that cannot be used; the message says what is missing or wrong."""


def search_working_directory() -> None:
    """Put the working directory on the import path, as ``python -m`` does, so that ``mymodels.msd:Model`` is found
    where ``mymodels/`` is; but last, not first: a folder where the user works cannot shadow zencosim's or an
    installed package's modules (``manager.bus.children`` starts subsystem processes with ``-P`` for that reason;
    they inherit the working directory and search it the same way)."""
    directory = os.getcwd()
    if directory not in sys.path:
        sys.path.append(directory)


def find_class(reference: str) -> type:
    """The class ``"package.module:ClassName"``, or the one a package registered under ``reference``."""
    if ":" not in reference:
        registered = {e.name: e for e in entry_points(group=ENTRY_POINTS)}
        if reference not in registered:
            raise ModelClassError(f"no model {reference!r}: expected a built-in model, 'fmu', 'package.module:Class' "
                                  f"or a name registered in the entry-point group {ENTRY_POINTS!r}"
                                  + (f" ({', '.join(sorted(registered))})" if registered else ""))
        reference = registered[reference].value
    module_name, _, class_name = reference.partition(":")
    search_working_directory()
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ModelClassError(f"model {reference!r}: cannot import module {module_name!r}: {error}") from None
    except (Exception, SystemExit) as error:  # the user's module failed (or called sys.exit) while it was imported
        raise ModelClassError(f"model {reference!r}: importing {module_name!r} failed: "
                              f"{type(error).__name__}: {error}") from None
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type):
        raise ModelClassError(f"model {reference!r}: module {module_name!r} has no class {class_name!r}")
    return cls


def describe_python(reference: str, cls: type) -> ComponentDescription:
    """The class as a component; :class:`ModelClassError` listing every problem of its declarations."""
    problems = []
    declared = {}
    for attribute in ("inputs", "outputs"):
        table = getattr(cls, attribute, None)
        if not isinstance(table, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in table.items()):
            problems.append(f"{attribute}: expected a dict of variable name -> SI unit, e.g. {{'x': 'm'}}")
            table = {}
        declared[attribute] = table
    parameters = getattr(cls, "parameters", {})
    if not isinstance(parameters, dict):
        problems.append("parameters: expected a dict of name -> default value")
        parameters = {}
    clashes = set(declared["inputs"]) & set(declared["outputs"])
    if clashes:
        problems.append(f"names declared as both input and output: {', '.join(sorted(clashes))}")
    second_order = bool(getattr(cls, "second_order", False))
    needed = ["initial_state", "outputs_at", "acceleration" if second_order else "derivative"]
    for method in needed:
        if not callable(getattr(cls, method, None)):
            problems.append(f"missing method {method}()" + (" (second_order = True)" if method == "acceleration" else ""))
    feedthrough = _feedthrough(cls, declared, problems)
    variables = {}
    for causality in ("inputs", "outputs"):
        for name, unit in declared[causality].items():
            try:
                found, problem = exponents(unit), None
            except UnitError as error:
                found, problem = None, f"unit {error}"
                problems.append(f"{causality[:-1]} {name}: {problem}")
            variables[name] = Variable(name, causality[:-1], unit, found, problem,
                                       feedthrough.get(name, ()) if causality == "outputs" else None)
    for name in parameters:
        variables.setdefault(name, Variable(name, "parameter", None, None, "a parameter"))
    if problems:
        raise ModelClassError(f"model {reference}: " + "; ".join(problems))
    return ComponentDescription(f"Python model {reference}", "ode", variables, True, second_order)


def _feedthrough(cls: type, declared: dict, problems: list) -> dict[str, tuple[str, ...]]:
    """Per output, the inputs it depends on directly: ``feedthrough`` is a dict output -> inputs, or a list
    of outputs that depend on every input; outputs not named depend on none."""
    raw = getattr(cls, "feedthrough", ())
    inputs = tuple(declared["inputs"])
    table = raw if isinstance(raw, dict) else {name: inputs for name in raw}
    result = {}
    for output, depends in table.items():
        depends = tuple(depends)
        if output not in declared["outputs"]:
            problems.append(f"feedthrough names {output!r}, which is not an output")
        unknown = set(depends) - set(inputs)
        if unknown:
            problems.append(f"feedthrough of {output}: {', '.join(sorted(unknown))} are not inputs")
        result[output] = depends
    return result


class PythonInstance:
    """The user's model for one subsystem: inputs and outputs exchanged in the order zencosim asked for,
    inputs zencosim does not set held at 0."""

    def __init__(self, cls: type, description: ComponentDescription, start: dict[str, float],
                 inputs: tuple[str, ...], outputs: tuple[str, ...]) -> None:
        parameters = {**getattr(cls, "parameters", {}), **start}
        try:
            self.model = cls(**parameters)
        except (Exception, SystemExit) as error:  # the user's constructor: named, never a traceback
            raise ModelClassError(f"model {cls.__module__}:{cls.__qualname__}: its constructor raised "
                                  f"{type(error).__name__}: {error}") from None
        declared_inputs = tuple(cls.inputs)
        self._u = np.zeros(len(declared_inputs))
        self._input_at = np.array([declared_inputs.index(name) for name in inputs], dtype=np.intp)
        self._output_at = np.array([tuple(cls.outputs).index(name) for name in outputs], dtype=np.intp)
        self._evaluate = self.model.acceleration if description.second_order else self.model.derivative

    def _full(self, u: np.ndarray) -> np.ndarray:
        full = self._u.copy()
        full[self._input_at] = u
        return full

    def initial_state(self) -> np.ndarray:
        return np.array(self.model.initial_state(), dtype=np.float64)

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.asarray(self._evaluate(t, z, self._full(u)), dtype=np.float64)

    def outputs(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.asarray(self.model.outputs_at(t, z, self._full(u)), dtype=np.float64)[self._output_at]
