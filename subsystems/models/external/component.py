"""What zencosim knows of a component it does not implement itself (an FMU, a user's Python model): its
variables with causality and unit, how it is advanced, and what it can do.

Two ways of advancing a component:

* ``"ode"``: the component gives its state derivative (an FMU for Model Exchange, a Python model)
  and zencosim's integrator advances the state ``z``, which zencosim owns; saving and restoring the
  subsystem copies ``z``;
* ``"co-simulation"``: the component advances itself over a micro-step (an FMU for Co-Simulation,
  ``doStep``); its state is its own, saved and restored through the component (FMI's FMU state).

A running component is an :class:`Instance`: it is told which of its inputs zencosim sets and which
outputs it reads, in the order of the arrays it then exchanges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from zencosim.subsystems.units import Exponents

Interface = Literal["ode", "co-simulation"]


@dataclass(frozen=True)
class Variable:
    """One real variable of a component."""

    name: str
    causality: str  # "input", "output", "parameter", "local", …
    unit: str | None  # as the component declares it (or the scene, where the component declares none or
    # a dimensionless one: ``declared_unit``)
    exponents: Exponents | None  # its SI base-unit exponents; None when undeclared or unknown
    unit_problem: str | None  # why ``exponents`` is None
    depends_on: tuple[str, ...] | None = None  # an output's direct dependence on inputs; None: on every input
    factor: float = 1.0  # the unit in SI: value_SI = factor * value + offset (FMI's BaseUnit)
    offset: float = 0.0
    kind: Literal["Real", "Integer", "Boolean"] = "Real"  # an Integer or Boolean travels as a float64 too
    minimum: float = -math.inf  # the range the component declares (FMI min and max), SI
    maximum: float = math.inf
    declared_unit: str | None = None  # the component's own unit, where the scene's replaced it (units.replaceable)

    @property
    def discrete(self) -> bool:
        """An Integer or Boolean variable: exchanged by signal connections only, held over a step."""
        return self.kind != "Real"

    @property
    def converted(self) -> bool:
        """Whether its values are converted at the component's boundary (its unit is not the SI one)."""
        return self.factor != 1.0 or self.offset != 0.0

    def to_component(self, si_value: float) -> float:
        """An SI value in the component's unit: (value - offset) / factor."""
        return (si_value - self.offset) / self.factor if self.converted else si_value


@dataclass(frozen=True)
class ComponentDescription:
    """A component as loaded at scene time (nothing is instantiated yet)."""

    kind: str  # "FMI 2.0 Co-Simulation", "Python model", … (for messages)
    interface: Interface
    variables: dict[str, Variable]
    can_save_state: bool  # FMI canGetAndSetFMUstate; ODE components always (zencosim holds z)
    second_order: bool = False  # ODE: z = [q, q̇] and the component gives accelerations (n_dof)
    identity: tuple[tuple[str, str], ...] = ()  # what identifies the component's file (FMU: guid, sha256)
    variable_step: bool = True  # FMI canHandleVariableCommunicationStepSize (co-simulation); ODE components always

    @property
    def inputs(self) -> tuple[str, ...]:
        """The real inputs (Integer and Boolean ones are named by the signal connections that feed them)."""
        return tuple(name for name, v in self.variables.items() if v.causality == "input" and not v.discrete)

    @property
    def outputs(self) -> tuple[str, ...]:
        """The real outputs."""
        return tuple(name for name, v in self.variables.items() if v.causality == "output" and not v.discrete)


class Instance(Protocol):
    """A running component that exchanges the inputs and outputs it was created for, as float64 arrays."""

    def initial_state(self) -> np.ndarray:
        """ODE: ``z0`` (``[q0, q̇0]`` for a second-order component); co-simulation: an empty array."""

    def outputs(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The outputs at time ``t`` [s] with state ``z`` (ODE) and inputs ``u``."""

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """ODE, first order: ``ż``. Second order: the accelerations (``n_dof`` values)."""

    def do_step(self, t: float, h: float, u: np.ndarray) -> None:
        """Co-simulation: advance from ``t`` by ``h`` [s] with inputs ``u`` held over the step."""

    def save_state(self) -> object:
        """Co-simulation: the component's state, to be given back to ``restore_state``."""

    def restore_state(self, state: object) -> None:
        """Co-simulation: go back to a state ``save_state`` returned."""
