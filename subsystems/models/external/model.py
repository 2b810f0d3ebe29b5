"""External models: an FMU or a user's Python model as a zencosim subsystem model (docs/models.md).

A scene names the component (``model = "fmu"`` with ``fmu = "path.fmu"``, or ``model =
"package.module:Class"``), its start values and parameters (``start.<variable> = value``, SI), an
optional energy output (``energy = "<variable>"``, [J]), the SI units of variables the component
declares none for (``units.<variable> = "unit"``), per point the variables that play each coupling
role (``points.<point> = { role = "<variable>", … }``, ``subsystems.models.external.points``) and the
output variables it publishes besides (``outputs = ["x", "v"]``, or ``"all"``: every output, as
``fmpy simulate`` records them; ports named after the variables) and a table of values over time for
inputs no coupling feeds (``input_table = "inputs.csv"``, ``subsystems.models.external.table``) and what its
outputs depend on at the same instant where the component omits it (``feedthrough = { y = ["u"] }``,
``subsystems.models.external.feedthrough``). The
model's ports are then made from
what the couplings attach to each point, exactly as for a built-in model, and from the variables signal
connections name; their names are the couplings' signals, their units the roles' SI quantities, and the
component's units must be of those quantities (a mismatch is a scene error naming the variable).

Units with a factor and offset (an FMU's unit definition: value_SI = factor * value + offset, such as
``mm``, ``bar`` or ``degC``) are converted at the component's boundary: an output to SI before zencosim
uses it, an input and a start value from SI into the component's unit, ``(value - offset) / factor``.

The component computes a coupling force itself (``provides_force``): a force–displacement coupling on
an external force side has no coupling element of zencosim's.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np

from zencosim.subsystems.models.external.component import ComponentDescription, Variable
from zencosim.subsystems.models.external.feedthrough import apply_feedthrough, read_feedthrough
from zencosim.subsystems.models.external.fmu import FmuError, describe_fmu, open_fmu
from zencosim.subsystems.models.external.points import ROLES, PointMap
from zencosim.subsystems.models.external.python_model import (
    ModelClassError,
    PythonInstance,
    describe_python,
    find_class,
)
from zencosim.subsystems.models.external.table import InputTable, read_input_table
from zencosim.subsystems.params import Problems, check_value, read_table
from zencosim.subsystems.ports import UNITS, Attachments, Port
from zencosim.subsystems.straight_line import StepText
from zencosim.subsystems.units import UnitError, describe, exponents, replaceable, unit_contradiction


@dataclass(frozen=True)
class ExternalSettings:
    """The model's own keys of a ``[subsystems.<name>]`` table (``start`` and ``points`` are tables)."""

    fmu: str | None = None  # FMU models: its path, relative to the scene file
    interface: Literal["co-simulation", "model-exchange"] | None = None  # FMU models (default: co-simulation)
    energy: str | None = None  # an output variable with the component's energy [J]
    outputs: str | tuple[str, ...] = ()  # output variables published besides the couplings' ("all": every one)
    input_table: str | None = None  # a CSV table of input values over time, relative to the scene file


@dataclass(frozen=True)
class ExternalSpec:
    """An external model as a scene describes it, with its component's description (its traits included)."""

    reference: str  # "fmu" or "package.module:Class"
    description: ComponentDescription
    source: Any  # the FMU's Path, or the model class
    start: dict[str, float]
    energy: str | None
    point_maps: dict[str, PointMap]
    published: tuple[str, ...] = ()  # output variables published as signals of their own name
    input_table: InputTable | None = None  # inputs given over time
    feedthrough: dict[str, tuple[str, ...]] | None = None  # the scene's feedthrough key (applied to description)
    provides_force = True  # the component computes its coupling forces
    starts_at_rest = False
    can_project = False  # no projection step (paper 003 Eq. 30): the state is the component's
    coupling_roles = frozenset({"force", "motion"})

    @property
    def points(self) -> tuple[str, ...]:
        return tuple(self.point_maps)

    @property
    def identity(self) -> dict[str, str]:
        """What identifies the component's file to the other processes of a run (an FMU's GUID and sha256)."""
        return dict(self.description.identity)

    @property
    def replaced_units(self) -> dict[str, tuple[str, str]]:
        """variable -> (the unit the component declares, the scene's that replaced it: :func:`apply_units`)."""
        return {name: (v.declared_unit, v.unit) for name, v in self.description.variables.items()
                if v.declared_unit is not None}

    @property
    def second_order(self) -> bool:
        return self.description.second_order

    @property
    def can_save_state(self) -> bool:
        return self.description.can_save_state

    @property
    def variable_step(self) -> bool:
        return self.description.variable_step

    @property
    def point_dimension(self) -> int:
        dimensions = {m.dimension for m in self.point_maps.values()}
        return dimensions.pop() if len(dimensions) == 1 else 1

    @property
    def advances_itself(self) -> bool:
        return self.description.interface == "co-simulation"

    def role_problem(self, point: str, role: str, domain: str = "translational", displacement: bool = True
                     ) -> str | None:
        """Why ``point`` cannot be the ``role`` ("force" or "motion") side of a power bond of ``domain``
        (``displacement``: whether the bond exchanges the displacement too)."""
        point_map = self.point_maps[point]
        if point_map.domain != domain:
            return f"points.{point} is {point_map.domain} (its domain key); the coupling is {domain}"
        needed = ("force", "position_input", "velocity_input") if role == "force" else ("force_input", "position",
                                                                                          "velocity")
        missing = [r for r in needed if getattr(point_map, r) is None and (displacement or "position" not in r)]
        return f"points.{point} needs the roles {', '.join(missing)} for the {role} side" if missing else None

    def drive_problem(self, point: str, drive: str, axes: int) -> str | None:
        return self.point_maps[point].can_drive(drive)

    def linear_problem(self) -> str | None:
        return f"a {self.description.kind} is not known to be linear"

    def feedthrough_origin(self, key: str) -> str | None:
        """Who says what its outputs depend on at the same instant, for the message of an algebraic loop through
        them (``key``: its table's); None where its model class does."""
        if self.feedthrough is not None:
            return f"as {key}.feedthrough states it"
        if self.reference == "fmu":
            return f"as its modelDescription declares it, which {key}.feedthrough overrides"
        return None

    def variable_problem(self, name: str, end: Literal["output", "input"]) -> str | None:
        """Why the variable ``name`` cannot be the ``end`` of a signal connection (None: it can)."""
        variable = self.description.variables.get(name)
        if variable is None:
            return f"the {self.description.kind} has no variable {name!r} of type Real, Integer or Boolean"
        if variable.causality != end:
            return f"{name} is {variable.causality}; expected an {end}"
        return None


class ExternalModel:
    """The zencosim model interface over a component instance (see the module text)."""

    name = "external"

    @classmethod
    def traits(cls, spec: ExternalSpec) -> ExternalSpec:
        """What this model can do depends on its component: the spec says it."""
        return spec

    @classmethod
    def describe(cls, settings: ExternalSettings, directory: Path) -> tuple[ComponentDescription, Any]:
        raise NotImplementedError

    @classmethod
    def read(cls, table: dict, key: str, problems: Problems, directory: Path) -> ExternalSpec | None:
        """The component, its start values, energy variable and points; every problem recorded under ``key``."""
        before = len(problems)
        tables = ("start", "points", "units", "outputs", "feedthrough")  # read below
        settings = read_table(ExternalSettings, table, key, problems, skip=tables)
        if settings is None:
            return None
        try:
            description, source = cls.describe(settings, directory)
        except (FmuError, ModelClassError) as error:
            problems.add(f"{key}.{'fmu' if settings.fmu else 'model'}", str(error))
            return None
        description = apply_units(table.get("units"), description, f"{key}.units", problems)
        feedthrough = read_feedthrough(table.get("feedthrough"), description, f"{key}.feedthrough", problems)
        description = apply_feedthrough(feedthrough, description)
        start = read_start(table.get("start", {}), description, f"{key}.start", problems)
        published = read_published(table.get("outputs", ()), description, f"{key}.outputs", problems)
        input_table = None
        if settings.input_table is not None:
            input_table = read_input_table(settings.input_table, description, directory, f"{key}.input_table",
                                           problems)
        point_maps = {}
        points = table.get("points", {})
        if not isinstance(points, dict):
            problems.add(f"{key}.points", "expected points.<name> = { role = \"variable\", … } for every point a "
                         f"coupling attaches to; roles: {', '.join(ROLES)}")
            points = {}
        for point, point_table in points.items():
            point_map = read_table(PointMap, point_table, f"{key}.points.{point}", problems)
            if point_map is not None:
                _check_point(point_map, description, f"{key}.points.{point}", problems)
                point_maps[point] = point_map
        if settings.energy is not None:
            _check_variable(settings.energy, "output", "energy", description, f"{key}.energy", problems)
        if len(problems) != before:
            return None
        return ExternalSpec(cls.name, description, source, start, settings.energy, point_maps, published,
                            input_table, feedthrough)

    def __init__(self, spec: ExternalSpec, attachments: Attachments = Attachments(), expose_all: bool = False) -> None:
        """``expose_all``: a port for every input and output of the component, named after it, whatever the
        points say (``zencosim check-model``)."""
        self.spec = spec
        ports = _Ports(spec, attachments, expose_all)
        self.inputs: tuple[Port, ...] = tuple(ports.inputs)
        self.outputs: tuple[Port, ...] = tuple(ports.outputs)
        self.effects: tuple[str, ...] = ()
        self.second_order = spec.second_order
        self._u_scale = np.array(ports.u_scale)
        self._u_factor, self._u_offset = np.array(ports.u_factor), np.array(ports.u_offset)
        self._table = None if expose_all else spec.input_table
        self._u_convert = bool(np.any(self._u_factor != 1.0) or np.any(self._u_offset != 0.0))
        self._u_plain = self._table is None and not self._u_convert and bool(np.all(self._u_scale == 1.0))
        self._y = ports.assembly()
        variables = spec.description.variables
        self.component_start = {name: variables[name].to_component(value) for name, value in spec.start.items()}
        self.instance = self._open(ports.component_inputs, ports.component_outputs)
        if self.second_order:
            self.n_dof = len(self.instance.initial_state()) // 2
        if self._u_plain:  # zencosim's inputs are the component's: its own calls, one Python frame fewer a step
            if hasattr(self.instance, "do_step"):
                self.do_step = self.instance.do_step
            if self._y.identity:  # and its outputs zencosim's
                self.outputs_at = self.instance.outputs

    def _open(self, inputs: tuple[str, ...], outputs: tuple[str, ...]):
        raise NotImplementedError

    def _u(self, t: float, w: np.ndarray) -> np.ndarray:
        """The component's inputs at time ``t`` [s] from zencosim's (signed) and the input table's, converted
        into the component's units."""
        if self._u_plain:  # zencosim's inputs are the component's, in order, unscaled and in SI
            return w
        u = w * self._u_scale
        if self._table is not None:
            u = np.concatenate((u, self._table.at(t)))
        if self._u_convert:
            u = (u - self._u_offset) / self._u_factor
        return u

    def initial_state(self) -> np.ndarray:
        return self.instance.initial_state()

    def derivative(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return self.instance.derivative(t, z, self._u(t, w))

    def acceleration(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        return self.instance.derivative(t, z, self._u(t, w))

    def do_step(self, t: float, h: float, w: np.ndarray) -> None:
        self.instance.do_step(t, h, self._u(t, w))

    def outputs_at(self, t: float, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        component = self.instance.outputs(t, z, self._u(t, w))
        a = self._y
        if a.identity:  # the component's outputs, in order, in SI, untransformed (a fresh array)
            return component
        y = np.empty(len(self.outputs))
        if a.convert:  # to SI, then signed
            y[a.rows] = (component[a.indices] * a.factors + a.offsets) * a.scales
        else:
            y[a.rows] = component[a.indices] * a.scales
        if a.shift:
            y[a.rows] += a.shifts
        y[a.input_rows] = w[a.input_columns]
        y[a.constant_rows] = a.constants
        return y

    def step_text(self, prefix: str, start_ns: str, micro_steps: int, h_ns: int) -> StepText | None:
        """The component's own zero-order step as statements (``Subsystem.step_text``), where zencosim's inputs and
        outputs are the component's as they are and the component has such a text (a co-simulation FMU's:
        ``subsystems.models.external.fmu``); else None."""
        if not (self._u_plain and self._y.identity and hasattr(self.instance, "step_text")):
            return None
        return self.instance.step_text(prefix, start_ns, micro_steps, h_ns)

    def save_state(self) -> object | None:
        """The component's own state (co-simulation), or None when zencosim's ``z`` is the whole state."""
        return self.instance.save_state() if self.spec.description.interface == "co-simulation" else None

    def restore_state(self, state: object | None) -> None:
        if state is not None:
            self.instance.restore_state(state)


class FmuModel(ExternalModel):
    """An FMU (through fmpy): ``model = "fmu"``, ``fmu = "path.fmu"``."""

    name = "fmu"

    @classmethod
    def describe(cls, settings: ExternalSettings, directory: Path) -> tuple[ComponentDescription, Path]:
        if settings.fmu is None:
            raise FmuError("missing; expected the FMU's path, relative to the scene file: fmu = \"model.fmu\"")
        path = (directory / settings.fmu).resolve()
        return describe_fmu(path, settings.interface), path

    def _open(self, inputs: tuple[str, ...], outputs: tuple[str, ...]):
        return open_fmu(self.spec.source, self.spec.description, self.component_start, inputs, outputs,
                        f"zencosim:{self.spec.source.name}")


class PythonModel(ExternalModel):
    """A user's model class (``model = "package.module:Class"``); subclassed per class by :func:`python_model`."""

    model_class: type

    @classmethod
    def describe(cls, settings: ExternalSettings, directory: Path) -> tuple[ComponentDescription, type]:
        if settings.fmu is not None or settings.interface is not None:
            raise ModelClassError("fmu and interface belong to model = \"fmu\"")
        return describe_python(cls.name, cls.model_class), cls.model_class

    def _open(self, inputs: tuple[str, ...], outputs: tuple[str, ...]):
        return PythonInstance(self.spec.source, self.spec.description, self.component_start, inputs, outputs)


_PYTHON_MODELS: dict[str, type] = {}


def python_model(reference: str) -> type:
    """The model class for the user's class ``reference`` (``module:Class`` or an entry-point name), cached;
    :class:`ModelClassError` when it cannot be found."""
    if reference not in _PYTHON_MODELS:
        user_class = find_class(reference)
        _PYTHON_MODELS[reference] = type(f"PythonModel[{reference}]", (PythonModel,),
                                         {"name": reference, "model_class": user_class})
    return _PYTHON_MODELS[reference]


def read_published(value: Any, description: ComponentDescription, key: str, problems: Problems) -> tuple[str, ...]:
    """The ``outputs`` key: output variables by name, or "all" (every output of the component)."""
    if value == "all":
        return tuple(description.outputs)
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        problems.add(key, f"expected a list of output variables or \"all\", got {value!r}")
        return ()
    for name in value:
        variable = description.variables.get(name)
        if variable is None or variable.causality != "output":
            problems.add(key, f"{name!r} is not a real output of the {description.kind}; expected one of "
                              f"{', '.join(description.outputs) or '(none)'}")
    return tuple(dict.fromkeys(value))


def read_start(table: Any, description: ComponentDescription, key: str, problems: Problems) -> dict[str, float]:
    """The ``start`` table: values of the component's parameters, inputs and states by name, before it starts."""
    if not isinstance(table, dict):
        problems.add(key, "expected a table of variable = value")
        return {}
    start = {}
    for name, value in table.items():
        variable = description.variables.get(name)
        if variable is None or variable.discrete:
            problems.add(f"{key}.{name}", f"the {description.kind} has no real variable {name!r} (Integer and "
                                          "Boolean start values are not set)")
        elif variable.causality == "output":
            problems.add(f"{key}.{name}", f"{name} is an output of the {description.kind}; it cannot be set")
        else:
            number = check_value(float, value, f"{key}.{name}", problems)
            if number is not None:
                start[name] = number
    return start


def apply_units(table: Any, description: ComponentDescription, key: str,
                problems: Problems) -> ComponentDescription:
    """The description with the scene's ``units`` table (variable -> SI unit) applied: the unit of a variable
    the component declares none for, or one zencosim cannot read, or a dimensionless one (``1``; or one that
    differs from the scene's only in the radian: :func:`~zencosim.subsystems.units.replaceable`), which the
    scene's replaces, the component's factor and offset kept (``Variable.declared_unit`` remembers it). Any
    other unit the component declares is its own: the scene's must be of the same quantity, and the
    component's (with its factor and offset) is used."""
    if table is None:
        return description
    if not isinstance(table, dict):
        problems.add(key, 'expected a table of variable = "SI unit", e.g. units = { x_in = "m", fc = "N" }')
        return description
    variables = dict(description.variables)
    for name, unit in table.items():
        variable = variables.get(name)
        if variable is None:
            problems.add(f"{key}.{name}", f"the {description.kind} has no real variable {name!r}")
            continue
        if not isinstance(unit, str):
            problems.add(f"{key}.{name}", f'expected an SI unit as a string (e.g. "m", "N", "m/s"), got {unit!r}')
            continue
        try:
            found = exponents(unit)
        except UnitError as error:
            problems.add(f"{key}.{name}", f"{error}; give an SI unit (a unit with a factor or an offset comes "
                                          "from the component's own unit definitions)")
            continue
        if variable.exponents is None:
            variables[name] = replace(variable, unit=unit, exponents=found, unit_problem=None, factor=1.0, offset=0.0)
        elif replaceable(variable.exponents, found):
            variables[name] = replace(variable, unit=unit, exponents=found, declared_unit=variable.unit)
        elif variable.exponents != found:
            problems.add(f"{key}.{name}", unit_contradiction(name, description.kind, variable.unit, variable.exponents,
                                                             unit, found))
    return replace(description, variables=variables)


def _check_variable(name: str, causality: str, quantity: str, description: ComponentDescription, key: str,
                    problems: Problems) -> None:
    """``name`` is a variable of ``causality`` in the unit of ``quantity`` (SI)."""
    variable = description.variables.get(name)
    if variable is None or variable.discrete:
        candidates = [v for v, d in description.variables.items() if d.causality == causality and not d.discrete]
        problems.add(key, f"the {description.kind} has no real variable {name!r}; its {causality}s: "
                     f"{', '.join(candidates) or 'none'}")
        return
    if variable.causality != causality:
        problems.add(key, f"{name} is {'an' if variable.causality[0] in 'aeiou' else 'a'} {variable.causality} of the "
                     f"{description.kind}; expected an {causality}")
    expected = UNITS[quantity]
    if variable.exponents is None:
        problems.add(key, f"{name}: {variable.unit_problem}; expected [{expected}] ({quantity}): declare it in the "
                     f'subsystem\'s units table, units = {{ {name} = "{expected}" }}')
    elif variable.exponents != exponents(expected):
        problems.add(key, f"{name} is in [{variable.unit}] ({describe(variable.exponents)}); expected [{expected}] "
                     f"({quantity})")


def _check_point(point_map: PointMap, description: ComponentDescription, key: str, problems: Problems) -> None:
    for role in point_map.roles():
        causality, quantity = ROLES[role][0], point_map.quantity(role)
        for name in point_map.variables(role):
            _check_variable(name, causality, quantity, description, f"{key}.{role}", problems)


@dataclass
class _Ports:
    """The ports an external model gets from its attachments, and how they map onto the component's variables."""

    spec: ExternalSpec
    attachments: Attachments
    expose_all: bool = False
    inputs: list[Port] = field(default_factory=list)
    outputs: list[Port] = field(default_factory=list)
    u_scale: list[float] = field(default_factory=list)  # per zencosim input: the sign it is applied with
    u_factor: list[float] = field(default_factory=list)  # per component input (the table's last): its unit,
    # SI = factor * value + offset
    u_offset: list[float] = field(default_factory=list)
    component_inputs: list[str] = field(default_factory=list)
    component_outputs: list[str] = field(default_factory=list)
    output_sources: list[tuple] = field(default_factory=list)  # per output: ("variable", index, scale, factor,
    # offset), ("input", column) or ("constant", value)

    def __post_init__(self) -> None:
        if self.expose_all:
            self._every_variable()
            return
        a, maps = self.attachments, self.spec.point_maps
        unsupported = [kind for kind, items in (("coupling effects", a.effects), ("rest states", a.rest_states),
                                                ("relayed forces", a.relayed_forces)) if items]
        if unsupported:
            raise ValueError(f"an external model cannot take {', '.join(unsupported)}")
        for terminal in a.terminals:
            self._input(terminal.position_inputs, maps[terminal.at], "position_input", 1.0)
            self._input(terminal.velocity_inputs, maps[terminal.at], "velocity_input", 1.0)
        for received in a.force_inputs:
            self._input(received.ports, maps[received.point], "force_input", received.sign)
        for side in a.joint_sides:
            point_map = maps[side.point]
            if side.drive == "force":
                self._input(side.inputs, point_map, "force_input", side.sign)
            else:
                self._input(side.inputs, point_map, "acceleration_input", 1.0)
        for motion in a.motion_outputs:
            self._output(motion.position_ports, maps[motion.point], "position")
            self._output(motion.velocity_ports, maps[motion.point], "velocity")
        for force in a.force_outputs:
            self._output(force.ports, maps[force.point], "force", force.factor)
        for side in a.joint_sides:
            self._joint_outputs(side, maps[side.point])
        description = self.spec.description
        for received in a.signal_inputs:
            self._feed(replace(_port_of(received.variable, description), name=received.port), received.variable, 1.0)
        for sent in a.signal_outputs:
            self._variable_output(replace(_port_of(sent.variable, description), name=sent.port), sent.variable,
                                  sent.factor, sent.offset)
        if self.spec.energy is not None:
            self._variable_output(Port("energy", "energy"), self.spec.energy, 1.0)
        table = self.spec.input_table
        for name in () if table is None else table.variables:  # after every coupling's: _u appends them
            if name in self.component_inputs:
                raise ValueError(f"input {name} of the component is fed by a coupling and by {table.path.name}")
            self.component_inputs.append(name)
            variable = self.spec.description.variables[name]
            self.u_factor.append(variable.factor)
            self.u_offset.append(variable.offset)
        taken = {port.name for port in self.outputs}
        for name in self.spec.published:
            if name not in taken:
                self._variable_output(_port_of(name, description), name, 1.0)

    def _every_variable(self) -> None:
        description = self.spec.description
        for name in description.inputs:
            self._feed(_port_of(name, description), name, 1.0)
        for name in description.outputs:
            self._variable_output(_port_of(name, description), name, 1.0)

    def _input(self, ports: tuple[str, ...], point_map: PointMap, role: str, sign: float) -> None:
        for port, variable in zip(ports, point_map.variables(role)):
            self._feed(Port(port, point_map.quantity(role)), variable, sign)

    def _feed(self, port: Port, variable: str, sign: float) -> None:
        """The zencosim input ``port`` feeds the component input ``variable``, times ``sign`` (zencosim's inputs
        are the component's first ones, in the same order)."""
        if variable in self.component_inputs:
            raise ValueError(f"input {variable} of the component is fed twice (ports {port.name} and another)")
        self.inputs.append(port)
        unit = self.spec.description.variables[variable]
        self.component_inputs.append(variable)
        self.u_scale.append(sign)
        self.u_factor.append(unit.factor)
        self.u_offset.append(unit.offset)

    def _direct_inputs(self, variable: str) -> tuple[str, ...]:
        """The zencosim input ports a component output depends on at the same instant."""
        depends = self.spec.description.variables[variable].depends_on
        return tuple(port.name for port, name in zip(self.inputs, self.component_inputs)
                     if depends is None or name in depends)

    def _variable_output(self, port: Port, variable: str, scale: float, shift: float = 0.0) -> None:
        """An output port with the value of the component's ``variable``, in SI, times ``scale`` plus ``shift``
        (a connection's linear transformation)."""
        if variable not in self.component_outputs:
            self.component_outputs.append(variable)
        direct = self._direct_inputs(variable)
        undeclared = bool(direct) and self.spec.description.variables[variable].depends_on is None
        self.outputs.append(Port(port.name, port.quantity, bool(direct), port.signal_unit, direct,
                                 undeclared=undeclared))
        unit = self.spec.description.variables[variable]
        self.output_sources.append(("variable", self.component_outputs.index(variable), scale, unit.factor,
                                    unit.offset, shift))

    def _output(self, ports: tuple[str, ...], point_map: PointMap, role: str, scale: float = 1.0) -> None:
        for port, variable in zip(ports, point_map.variables(role)):
            self._variable_output(Port(port, point_map.quantity(role)), variable, scale)

    def _joint_outputs(self, side, point_map: PointMap) -> None:
        self._output(side.positions, point_map, "position")
        self._output(side.velocities, point_map, "velocity")
        self._output(side.accelerations, point_map, "acceleration")
        if point_map.joint_force is not None:  # the joint's force on the point, in the sign of side 1
            self._output(side.forces, point_map, "joint_force", side.sign)
        else:  # force drive: the applied force sign × λ*, so f = λ*, the input itself
            for port, received in zip(side.forces, side.inputs):
                self.outputs.append(Port(port, "force", feedthrough=True, depends_on=(received,)))
                self.output_sources.append(("input", [p.name for p in self.inputs].index(received)))
        if isinstance(point_map.inverse_mass, float):
            for port in side.inverse_masses:
                self.outputs.append(Port(port, "inverse_mass"))
                self.output_sources.append(("constant", point_map.inverse_mass))
        else:
            self._output(side.inverse_masses, point_map, "inverse_mass")

    def assembly(self) -> _Assembly:
        """Index arrays that assemble the outputs from the component's outputs and the inputs."""
        def select(kind: str, position: int):
            return [s[position] for s in self.output_sources if s[0] == kind]

        rows = {kind: np.array([i for i, s in enumerate(self.output_sources) if s[0] == kind], dtype=np.intp)
                for kind in ("variable", "input", "constant")}
        factors, offsets = np.array(select("variable", 3)), np.array(select("variable", 4))
        shifts, scales = np.array(select("variable", 5)), np.array(select("variable", 2))
        indices = np.array(select("variable", 1), dtype=np.intp)
        convert, shift = bool(np.any(factors != 1.0) or np.any(offsets != 0.0)), bool(np.any(shifts != 0.0))
        every = np.arange(len(self.output_sources))
        identity = (not convert and not shift and bool(np.all(scales == 1.0))
                    and np.array_equal(rows["variable"], every) and np.array_equal(indices, every)
                    and len(self.component_outputs) == len(every))
        return _Assembly(rows["variable"], indices, scales, factors, offsets, convert, shifts, shift,
                         rows["input"], np.array(select("input", 1), dtype=np.intp), rows["constant"],
                         np.array(select("constant", 1)), identity)


class _Assembly(NamedTuple):
    """How an external model's outputs are assembled, as index arrays (one numpy operation per kind):
    ``y[rows] = (component[indices] * factors + offsets) * scales + shifts`` (to SI, then a connection's
    linear transformation; without the conversion where ``convert`` is false, without the shifts where
    ``shift`` is), ``y[input_rows] = w[input_columns]``, ``y[constant_rows] = constants``."""

    rows: np.ndarray
    indices: np.ndarray
    scales: np.ndarray
    factors: np.ndarray
    offsets: np.ndarray
    convert: bool
    shifts: np.ndarray
    shift: bool
    input_rows: np.ndarray
    input_columns: np.ndarray
    constant_rows: np.ndarray
    constants: np.ndarray
    identity: bool  # every output is a component output, in order, as it is: y is the component's array


def _port_of(name: str, description: ComponentDescription) -> Port:
    """A port for a component variable: a coupling quantity when its unit is one, else a signal in its SI unit
    (a variable without a unit zencosim can read, which ``check-model`` reports, is passed on as it is: "1")."""
    variable = description.variables[name]
    if variable.exponents is None:
        return Port(name, "signal", signal_unit="1", discrete=variable.discrete)
    if variable.exponents == exponents(UNITS["energy"]):  # energy or torque: a signal in the unit it declares
        return Port(name, "signal", signal_unit=_si_name(variable))
    for quantity, unit in UNITS.items():
        if variable.exponents == exponents(unit):
            return Port(name, quantity)
    return Port(name, "signal", signal_unit=_si_name(variable))


def _si_name(variable: Variable) -> str:
    """The SI unit of a variable: as declared where that is an SI unit string, else its base units."""
    if not variable.converted:
        try:
            if exponents(variable.unit) == variable.exponents:
                return variable.unit
        except UnitError:
            pass
    return describe(variable.exponents)
