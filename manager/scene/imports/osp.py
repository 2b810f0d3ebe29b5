"""OSP system structures (libcosim's ``OspSystemStructure.xml``) as zencosim scene documents.

The format is libcosim's (``data/xsd/OspSystemStructure.xsd``, ``src/cosim/osp_config_parser.cpp``):
``StartTime``, ``EndTime``, ``BaseStepSize`` (default 0.1 s), ``Algorithm`` (``fixedStep``, default, or
``ecco``), ``Simulators`` (``Simulator`` with ``name``, ``source`` — an FMU path or ``file:`` URI relative
to the file — ``stepSize`` and ``InitialValues``), ``Functions`` and ``Connections``:
``VariableConnection`` (two ``Variable`` elements, an optional ``powerBond`` name shared by exactly two
connections), ``VariableGroupConnection`` (two ``VariableGroup`` elements naming variable groups),
``SignalConnection`` and ``SignalGroupConnection`` (to functions). Variable groups are declared, per the
OSP Interface Specification, in ``<modelName>_OspModelDescription.xml`` beside the FMU, else beside the
system structure (libcosim's lookup): ``VariableGroups`` holding typed groups (``LinearMechanicalPort``
of a ``Force`` and a ``LinearVelocity``, ``AngularMechanicalPort`` of a ``Torque`` and an
``AngularVelocity``, ``HydraulicPort`` of a ``Pressure`` and a ``VolumeFlowRate``, ``ElectromagneticPort``
of a ``Voltage`` and a ``Current``, the quasi ports of an effort and a displacement, the displacement
groups ``LinearDisplacement``, ``AngularDisplacement``, ``Volume``, ``Charge``, ``Generic``, …) of
``Variable ref=…`` elements, with optional ``UnitDefinitions``.

A power bond, of the domain its port type or its units say (translational, rotational, hydraulic,
electrical), is declared: a ``VariableGroupConnection`` of two port groups, or connections (an effort and
a flow, and displacements if any) sharing a ``powerBond`` name (libcosim's marker), or a quasi port
connection together with the one flow connection from its motion side to its force side (a quasi port has
no flow, which zencosim's bond needs: without it the file is refused). Its force side is the simulator
whose effort variables are outputs (FMU causality). Its displacement is a displacement group connection or
plain connections of variables in the domain's displacement unit, from the motion side's outputs to the
force side's inputs; without one the coupling's displacement is ``[]``. Every other connection of real
variables is a ``signal`` coupling: the output's value copied into the input, as libcosim copies it.
A simulator coupled to nothing runs free and publishes its outputs. Functions (and the signal connections
to them) are refused. Namespaces are ignored (OSP has used several).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse
from urllib.request import url2pathname

from zencosim.manager.scene.imports import (
    BASE,
    BOND_DOMAINS,
    BOND_ROLES,
    MIXED,
    QUANTITIES,
    Bond,
    Component,
    Link,
    UnitDefinition,
    add_start,
    build_document,
    check_bond,
    children,
    document_path,
    link_quantity,
    local,
    note_unread,
    number,
    orient,
    parse_xml,
    read_fmu,
    same_quantity,
    scene_name,
    set_timing,
    settle_duration,
    where,
)
from zencosim.manager.scene.load import SceneError
from zencosim.subsystems.params import Problems

ROOT_ELEMENTS = ("StartTime", "EndTime", "BaseStepSize", "Algorithm", "Simulators", "Functions", "Connections",
                 "EccoConfiguration", "Description")
LIBCOSIM_BASE_STEP = 0.1  # [s] libcosim's BaseStepSize when the file gives none
ECCO_QUANTUM = 1e-9  # [s] an ecco system's manager.macro_step: libcosim counts a step in whole nanoseconds
ECCO_PARAMETERS = {  # EccoConfiguration's elements (libcosim's osp_config_parser) -> [manager.energy_control]
    "SafetyFactor": "safety_factor", "StepSize": "step_size", "MinimumStepSize": "min_step_size",
    "MaximumStepSize": "max_step_size", "MinimumChangeRate": "min_change_rate", "MaximumChangeRate": "max_change_rate",
    "ProportionalGain": "p_gain", "IntegralGain": "i_gain", "RelativeTolerance": "rel_tolerance",
    "AbsoluteTolerance": "abs_tolerance"}
GROUP_QUANTITIES = {  # OSP-IS groups of one quantity (effort, flow, displacement of each domain)
    "Force": "force", "LinearVelocity": "velocity", "LinearDisplacement": "displacement",
    "Torque": "torque", "AngularVelocity": "angular_velocity", "AngularDisplacement": "angle",
    "Pressure": "pressure", "VolumeFlowRate": "volume_flow", "Volume": "volume",
    "Voltage": "voltage", "Current": "current", "Charge": "charge"}
PORTS = {  # OSP-IS port -> (domain, its effort group, its flow group)
    "LinearMechanicalPort": ("translational", "Force", "LinearVelocity"),
    "AngularMechanicalPort": ("rotational", "Torque", "AngularVelocity"),
    "HydraulicPort": ("hydraulic", "Pressure", "VolumeFlowRate"),
    "ElectromagneticPort": ("electrical", "Voltage", "Current")}
QUASI_PORTS = {  # OSP-IS quasi port -> (domain, its effort group, its displacement group): no flow
    "LinearMechanicalQuasiPort": ("translational", "Force", "LinearDisplacement"),
    "AngularMechanicalQuasiPort": ("rotational", "Torque", "AngularDisplacement"),
    "HydraulicQuasiPort": ("hydraulic", "Pressure", "Volume"),
    "ElectromagneticQuasiPort": ("electrical", "Voltage", "Charge")}
KNOWN_GROUPS = (*PORTS, *QUASI_PORTS, *GROUP_QUANTITIES, "Generic")


@dataclass
class _Port:
    """A connection of two port groups: the effort one way, the flow (a port) or the displacement (a quasi
    port) back."""

    key: str
    domain: str
    effort: Link
    flow: Link | None  # None: a quasi port (its flow comes from another connection)
    displacement: Link | None  # a quasi port's
    bond: str | None  # its powerBond name
    names: tuple[str, str]  # the groups' names: force side, motion side
    kind: str  # its group type


class _Group:
    """A variable group of an OSP model description: its type, name, variables (with units) and sub-groups."""

    def __init__(self, element, label: str) -> None:
        self.type = local(element)
        self.name = element.get("name")
        self.key = where(element, f"{label}: ")
        self.variables = [(v.get("ref"), v.get("unit")) for v in children(element, "Variable")]
        self.groups = [_Group(c, label) for c in children(element) if local(c) != "Variable"]

    def walk(self):
        yield self
        for group in self.groups:
            yield from group.walk()


class _ModelDescription:
    """An ``<modelName>_OspModelDescription.xml``: its groups by name and its unit definitions."""

    def __init__(self, path: Path, problems: Problems) -> None:
        self.label = path.name
        self.groups: dict[str, _Group] = {}
        self.units: dict[str, UnitDefinition] = {}
        try:
            data = path.read_bytes()
        except OSError as error:
            problems.add(self.label, f"cannot read: {error.strerror or error}")
            return
        root = parse_xml(data, self.label, problems)
        if root is None:
            return
        if local(root) != "OspModelDescription":
            problems.add(self.label, f"expected an OspModelDescription, got a {local(root)!r} element")
            return
        for unit in (u for units in children(root, "UnitDefinitions") for u in children(units, "Unit")):
            base = children(unit, "BaseUnit")
            key = where(unit, f"{self.label}: ")
            if unit.get("name") is None:
                problems.add(key, "a Unit needs a name")
                continue
            if not base:
                self.units[unit.get("name")] = UnitDefinition(None)
                continue
            attributes = base[0].attrib
            try:
                exponents = tuple(int(attributes.get(b, "0")) for b in BASE)
                factor, offset = float(attributes.get("factor", "1")), float(attributes.get("offset", "0"))
            except ValueError as error:
                problems.add(key, f"BaseUnit: {error}")
                continue
            self.units[unit.get("name")] = UnitDefinition(exponents, factor, offset)
        groups = children(root, "VariableGroups")
        if len(groups) != 1:
            problems.add(self.label, f"expected one VariableGroups element, got {len(groups)}")
            return
        for top in children(groups[0]):
            for group in _Group(top, self.label).walk():
                if not group.name:
                    problems.add(group.key, "a variable group needs a name")
                elif group.name in self.groups:
                    problems.add(group.key, f"a second variable group named {group.name!r}")
                else:
                    self.groups[group.name] = group


class _Import:
    """One OSP system structure being read; problems and notes collect as it goes."""

    def __init__(self, path: Path, duration: float | None, algorithm: str | None = None,
                 units: dict[str, dict[str, str]] | None = None) -> None:
        self.path = path
        self.units = units or {}  # the scene's units of FMU variables, by subsystem (import_system)
        self.directory = path.parent
        self.duration = duration
        self.algorithm = algorithm  # "fixed": the user asks for the fixed-step algorithm whatever the file says
        self.problems = Problems()
        self.notes: list[str] = []
        self.components: dict[str, Component] = {}
        self.descriptions: dict[str, _ModelDescription | None] = {}
        self.declared_units: dict[tuple[str, str], str] = {}  # units OSP model descriptions state
        self.links: list[Link] = []
        self.ports: list[_Port] = []
        self.parsed: dict[Path, _ModelDescription] = {}
        self.failed: set[str] = set()  # simulators that could not be read
        self.energy_control: dict[str, float] | None = None  # an ecco system's [manager.energy_control]

    def run(self) -> tuple[dict, list[str]]:
        try:
            data = self.path.read_bytes()
        except OSError as error:
            raise self._refuse("file", f"cannot read: {error.strerror or error}") from None
        root = parse_xml(data, self.path.name, self.problems)
        if root is None:
            raise SceneError(str(self.path), self.problems)
        if local(root) != "OspSystemStructure":
            raise self._refuse(where(root), "expected an OspSystemStructure root element (an OSP system structure)")
        elements = self._root_elements(root)
        base_step, declared_end = self._simulation(elements)
        for simulators in elements.get("Simulators", []):
            for element in children(simulators):
                self._simulator(element, base_step)
        if "Simulators" not in elements:
            self.problems.add(where(root), "expected a Simulators element")
        elif not self.components:
            self.problems.add(where(elements["Simulators"][0]), "expected at least one Simulator")
        for functions in elements.get("Functions", []):
            for function in children(functions):
                self.problems.add(where(function), "OSP functions (LinearTransformation, Sum, VectorSum) are not "
                                                   "supported: zencosim has no function blocks; connect the "
                                                   "simulators' variables directly")
        for connections in elements.get("Connections", []):
            for element in children(connections):
                self._connection(element)
        bonds, signals = self._bonds()
        components = list(self.components.values())
        if self.energy_control is not None:  # libcosim's ECCO steps every simulator by the step it sets
            for component in components:
                component.step = ECCO_QUANTUM
            self.notes.append(f"manager.step_control = 'energy': the ecco algorithm, its parameters from "
                              f"EccoConfiguration (docs/system-imports.md); manager.macro_step = {ECCO_QUANTUM!r} s, "
                              "libcosim's resolution of a step; every simulator takes one step per macro-step, "
                              "whatever its stepSize, as libcosim's ECCO steps them")
        if base_step is not None:
            set_timing(base_step, "BaseStepSize", components, self.problems)
        duration = None
        if base_step is not None and not self.problems:
            duration = settle_duration(self.duration, declared_end, "EndTime - StartTime" if declared_end is not None
                                       else "the file gives no EndTime", base_step, components, self.problems,
                                       self.notes)
        if self.problems:
            raise SceneError(str(self.path), self.problems)
        name = self.directory.resolve().name if self.path.stem == "OspSystemStructure" else self.path.stem
        description = f"imported from the OSP system structure {self.path.name}"
        if "Description" in elements and (elements["Description"][0].text or "").strip():
            description += f": {elements['Description'][0].text.strip()}"
        document = build_document(name or self.path.stem, description, base_step, duration, components, bonds,
                                  self.notes, signals)
        if self.energy_control is not None:
            document["manager"].update(step_control="energy", energy_control=self.energy_control)
        return document, self.notes

    def _ecco(self, elements: dict, key: str) -> dict[str, float] | None:
        """[manager.energy_control] from the EccoConfiguration, which needs every parameter (libcosim's rule)."""
        if "EccoConfiguration" not in elements:
            self.problems.add(key, "algorithm 'ecco' needs an EccoConfiguration element with its parameters "
                                   f"({', '.join(ECCO_PARAMETERS)}), as libcosim does")
            return None
        configuration = elements["EccoConfiguration"][0]
        given = {local(child): child for child in children(configuration)}
        control = {}
        for element_name, parameter in ECCO_PARAMETERS.items():
            if element_name not in given:
                self.problems.add(where(configuration), f"no {element_name}: libcosim's ecco algorithm needs every "
                                                        f"parameter ({', '.join(ECCO_PARAMETERS)})")
                continue
            value = number(given[element_name].text, where(given[element_name]), element_name, self.problems)
            if value is not None:
                control[parameter] = value
        for element_name in given.keys() - ECCO_PARAMETERS.keys():
            self.problems.add(where(given[element_name]), f"unknown element; expected one of "
                                                          f"{', '.join(ECCO_PARAMETERS)}")
        return control

    def _refuse(self, key: str, reason: str) -> SceneError:
        self.problems.add(key, reason)
        return SceneError(str(self.path), self.problems)

    # the simulation ---------------------------------------------------------------------------------

    def _root_elements(self, root) -> dict[str, list]:
        elements: dict[str, list] = {}
        for element in children(root):
            name = local(element)
            if name not in ROOT_ELEMENTS:
                self.problems.add(where(element), f"unknown element; expected one of {', '.join(ROOT_ELEMENTS)}")
                continue
            if name in elements:
                self.problems.add(where(element), f"a second {name} element")
                continue
            elements[name] = [element]
        return elements

    def _value(self, elements: dict, name: str, what: str, positive: bool = False) -> float | None:
        if name not in elements:
            return None
        element = elements[name][0]
        return number(element.text, where(element), what, self.problems, positive)

    def _simulation(self, elements: dict) -> tuple[float | None, float | None]:
        """The base step and the declared duration (EndTime − StartTime); refusals for the rest."""
        start = self._value(elements, "StartTime", "the start time [s]")
        if start is not None and start != 0.0:
            self.problems.add(where(elements["StartTime"][0]), f"start time {start!r} s: zencosim starts every run, "
                                                               "and sets up its FMUs, at t = 0 s")
        end = self._value(elements, "EndTime", "the end time [s]")
        if "BaseStepSize" in elements:
            base_step = self._value(elements, "BaseStepSize", "the base step [s]", positive=True)
        else:
            base_step = LIBCOSIM_BASE_STEP
            self.notes.append(f"manager.macro_step = {LIBCOSIM_BASE_STEP} s: libcosim's default; the file gives no "
                              "BaseStepSize")
        algorithm = "fixedStep"
        if "Algorithm" in elements:
            algorithm = (elements["Algorithm"][0].text or "").strip()
            key = where(elements["Algorithm"][0])
            if algorithm.lower() == "ecco" and self.algorithm == "fixed":
                self.notes.append(f"{key}: 'ecco' (adaptive step size) run with the fixed-step algorithm at the base "
                                  "step, as asked (manager.algorithm = 'fixed')")
                algorithm = "fixedStep"
            elif algorithm.lower() == "ecco":
                self.energy_control = self._ecco(elements, key)
                base_step = ECCO_QUANTUM
            elif algorithm.lower() != "fixedstep":
                self.problems.add(key, f"unknown algorithm {algorithm!r}; expected fixedStep")
        if "EccoConfiguration" in elements and algorithm.lower() == "fixedstep":
            self.notes.append("EccoConfiguration ignored: the algorithm is fixed step")
        declared = None
        if end is not None:
            if end <= (start or 0.0):
                self.problems.add(where(elements["EndTime"][0]), f"end time {end!r} s: expected a time after the "
                                                                 f"start time {start or 0.0!r} s")
            else:
                declared = end - (start or 0.0)
        return base_step, declared

    def _simulator(self, element, base_step: float | None) -> None:
        key = where(element)
        if local(element) != "Simulator":
            self.problems.add(key, "unknown element; expected Simulator")
            return
        raw_name, source = element.get("name"), element.get("source")
        if not raw_name or not source:
            self.problems.add(key, "a Simulator needs a name and a source (the FMU)")
            return
        if raw_name in self.components or raw_name in self.failed:
            self.problems.add(key, f"a second simulator named {raw_name!r}")
            return
        self.failed.add(raw_name)
        fmu_path = self._fmu_file(source, key)
        if fmu_path is None:
            return
        fmu, reason = read_fmu(fmu_path, fmu_path.name)
        if fmu is None:
            self.problems.add(key, f"FMU {source}: {reason}")
            return
        if element.get("stepSize") is not None:
            step = number(element.get("stepSize"), key, "the stepSize [s]", self.problems, positive=True)
            if step is None:
                return
        elif base_step is not None:
            step = base_step
        else:
            return
        self.failed.discard(raw_name)
        name = scene_name(raw_name, {c.name for c in self.components.values()}, "the simulator", self.notes)
        if element.get("stepSize") is None and self.energy_control is None:
            self.notes.append(f"subsystems.{name}.micro_step = {step!r} s: {key} gives no stepSize; the base step, as "
                              "libcosim steps it")
        component = Component(name, key, fmu, document_path(fmu_path, self.directory), step,
                              units=dict(self.units.get(name, {})))
        self.components[raw_name] = component
        for initial in (v for values in children(element, "InitialValues") for v in children(values)):
            value_key = where(initial)
            typed = children(initial)
            if local(initial) != "InitialValue" or not initial.get("variable") or len(typed) != 1:
                self.problems.add(value_key, "expected InitialValue variable=\"…\" holding one Real, Integer, Boolean "
                                             "or String element")
                continue
            add_start(component, initial.get("variable"), local(typed[0]), typed[0].get("value"), value_key,
                      self.problems)
            note_unread(initial, ("variable",), value_key, self.notes)
            note_unread(typed[0], ("value",), value_key, self.notes)
        self.descriptions[raw_name] = self._model_description(fmu_path, fmu.model_name, key)

    def _fmu_file(self, source: str, key: str) -> Path | None:
        """The FMU a ``source`` URI names (a relative reference or a ``file:`` URI), if it exists."""
        parsed = urlparse(source)
        if parsed.scheme == "file":
            path = Path(url2pathname(parsed.path))
        elif parsed.scheme and len(parsed.scheme) > 1:  # not a Windows drive letter
            self.problems.add(key, f"source {source!r}: only FMU files are supported (a relative path or a file: URI), "
                                   f"not {parsed.scheme}: URIs")
            return None
        else:
            path = self.directory / unquote(source)
        if not path.is_file():
            self.problems.add(key, f"source {source!r}: no FMU file at {path}")
            return None
        return path

    def _model_description(self, fmu_path: Path, model_name: str, key: str) -> _ModelDescription | None:
        file_name = f"{model_name}_OspModelDescription.xml"
        for candidate in (fmu_path.parent / file_name, self.directory / file_name):
            if candidate.is_file():
                if candidate not in self.parsed:  # simulators of one FMU share it
                    self.parsed[candidate] = _ModelDescription(candidate, self.problems)
                return self.parsed[candidate]
        return None

    def _definitions(self) -> dict[str, dict[str, UnitDefinition]]:
        """The unit definitions of each subsystem's OSP model description."""
        return {c.name: d.units for s, c in self.components.items() if (d := self.descriptions.get(s)) is not None}

    # connections -----------------------------------------------------------------------------------

    def _connection(self, element) -> None:
        kind, key = local(element), where(element)
        if kind == "VariableConnection":
            self._variable_connection(element, key)
        elif kind == "VariableGroupConnection":
            self._group_connection(element, key)
        elif kind in ("SignalConnection", "SignalGroupConnection"):
            self.problems.add(key, "connections to OSP functions are not supported: zencosim has no function "
                                   "blocks")
        else:
            self.problems.add(key, "unknown element; expected VariableConnection or VariableGroupConnection")

    def _endpoints(self, element, tag: str, key: str) -> list[tuple[str, Component, str]] | None:
        found = children(element, tag)
        if len(found) != 2 or len(children(element)) != 2:
            self.problems.add(key, f"expected exactly two {tag} elements")
            return None
        endpoints = []
        for endpoint in found:
            simulator, name = endpoint.get("simulator"), endpoint.get("name")
            if not simulator or not name:
                self.problems.add(key, f"a {tag} needs a simulator and a name")
                return None
            if simulator in self.failed:  # reported where it is declared
                return None
            if simulator not in self.components:
                known = ", ".join(self.components) or "(none)"
                self.problems.add(key, f"unknown simulator {simulator!r}; expected one of {known}")
                return None
            endpoints.append((simulator, self.components[simulator], name))
        return endpoints

    def _variable_connection(self, element, key: str) -> None:
        endpoints = self._endpoints(element, "Variable", key)
        if endpoints is None:
            return
        (_, a, a_name), (_, b, b_name) = endpoints  # ECCO's causality labels of a powerBond are not needed
        oriented = orient(key, a, [a_name], b, [b_name], self.problems)
        if oriented is not None:
            self._add_link(key, oriented, None, element.get("powerBond"))

    def _add_link(self, key: str, oriented, quantity: str | None, bond: str | None) -> Link:
        source, outputs, target, inputs = oriented
        found = link_quantity(key, source, outputs, target, inputs, self.problems, self.declared_units,
                              self._definitions())
        if quantity is not None and found not in (None, MIXED) and not same_quantity(found, quantity):
            self.problems.add(key, f"a {quantity} group whose variables are in units of {found}")
        link = Link(key, source, outputs, target, inputs, quantity or found, bond)
        self.links.append(link)
        return link

    def _group_connection(self, element, key: str) -> None:
        endpoints = self._endpoints(element, "VariableGroup", key)
        if endpoints is None:
            return
        groups = []
        for simulator, component, name in endpoints:
            description = self.descriptions.get(simulator)
            if description is None:
                self.problems.add(key, f"simulator {simulator!r} has no OspModelDescription "
                                       f"({component.fmu.model_name}_OspModelDescription.xml beside its FMU or beside "
                                       f"{self.path.name}), so no variable group {name!r}")
                return
            if name not in description.groups:
                known = ", ".join(description.groups) or "(none)"
                self.problems.add(key, f"{description.label} declares no variable group {name!r}; it has {known}")
                return
            groups.append((component, description.groups[name]))
        (a, group_a), (b, group_b) = groups
        self._pair_groups(key, a, group_a, b, group_b, element.get("powerBond"))

    def _pair_groups(self, key: str, a: Component, group_a: _Group, b: Component, group_b: _Group,
                     bond: str | None) -> None:
        """Groups connected as libcosim connects them: of one type, variables and sub-groups pairwise."""
        if group_a.type != group_b.type:
            self.problems.add(key, f"connects a {group_a.type} ({a.name}.{group_a.name}) to a {group_b.type} "
                                   f"({b.name}.{group_b.name}); expected groups of one type")
            return
        if group_a.type not in KNOWN_GROUPS:
            self.problems.add(key, f"variable group type {group_a.type} ({a.name}.{group_a.name}) is not supported: "
                                   "zencosim couples the OSP-IS ports (LinearMechanicalPort, AngularMechanicalPort, "
                                   "HydraulicPort, ElectromagneticPort, their quasi ports), the groups of one "
                                   "quantity in them and Generic groups; see docs/system-imports.md")
            return
        for component, group in ((a, group_a), (b, group_b)):
            for ref, unit in group.variables:
                if ref and unit:
                    self.declared_units[(component.name, ref)] = unit
        if group_a.type in PORTS or group_a.type in QUASI_PORTS:
            self._port(key, a, group_a, b, group_b, bond)
            return
        if len(group_a.variables) != len(group_b.variables) or len(group_a.groups) != len(group_b.groups):
            self.problems.add(key, f"{a.name}.{group_a.name} and {b.name}.{group_b.name} differ in size "
                                   f"({len(group_a.variables)} and {len(group_b.variables)} variables, "
                                   f"{len(group_a.groups)} and {len(group_b.groups)} groups)")
            return
        if any(not ref for group in (group_a, group_b) for ref, _ in group.variables):
            self.problems.add(key, "a Variable of a group needs a ref")
            return
        quantity = GROUP_QUANTITIES.get(group_a.type)
        if quantity is not None:
            oriented = orient(key, a, [r for r, _ in group_a.variables], b, [r for r, _ in group_b.variables],
                              self.problems)
            if oriented is not None:
                self._add_link(key, oriented, quantity, bond)
        else:  # Generic: its variables pairwise, each a connection of its own, and its groups pairwise
            for (ref_a, _), (ref_b, _) in zip(group_a.variables, group_b.variables):
                oriented = orient(key, a, [ref_a], b, [ref_b], self.problems)
                if oriented is not None:
                    self._add_link(key, oriented, None, bond)
        for sub_a, sub_b in zip(group_a.groups, group_b.groups):
            self._pair_groups(key, a, sub_a, b, sub_b, bond)

    def _port(self, key: str, a: Component, group_a: _Group, b: Component, group_b: _Group, bond: str | None) -> None:
        """A port connection (both groups of one port type): its effort one way, its flow (or, a quasi port,
        its displacement) the other, each of the quantity of the port's domain."""
        kind = group_a.type
        quasi = kind in QUASI_PORTS
        domain, effort_type, other_type = (QUASI_PORTS if quasi else PORTS)[kind]
        parts = []
        for component, group in ((a, group_a), (b, group_b)):
            types = [g.type for g in group.groups]
            if sorted(types) != sorted([effort_type, other_type]) or group.variables:
                self.problems.add(key, f"{component.name}.{group.name}: a {kind} ({domain}) holds one {effort_type} "
                                       f"and one {other_type} group, got "
                                       f"{types + ['Variable'] * len(group.variables)}")
                return
            parts.append({g.type: g for g in group.groups})
        links = {}
        for part_type in (effort_type, other_type):
            refs = [[r for r, _ in part[part_type].variables] for part in parts]
            if not all(all(refs_) for refs_ in refs):
                self.problems.add(key, "a Variable of a group needs a ref")
                return
            oriented = orient(key, a, refs[0], b, refs[1], self.problems)
            if oriented is None:
                return
            source, outputs, target, inputs = oriented
            found = link_quantity(key, source, outputs, target, inputs, self.problems, self.declared_units,
                                  self._definitions())
            quantity = GROUP_QUANTITIES[part_type]
            if found is not None and found != MIXED and not same_quantity(found, quantity):
                self.problems.add(key, f"the {part_type} of {a.name}.{group_a.name} ({kind}, {domain}) is in units of "
                                       f"{found}; expected {QUANTITIES[quantity][0]} ({quantity})")
            links[part_type] = Link(key, source, outputs, target, inputs, quantity, bond)
        effort, other = links[effort_type], links[other_type]
        if effort.source is other.source:
            self.problems.add(key, f"{effort.source.name}.{group_a.name if effort.source is a else group_b.name} "
                                   f"outputs both {effort_type} and {other_type}; a port outputs one and receives "
                                   "the other")
            return
        port_names = (group_a.name, group_b.name) if effort.source is a else (group_b.name, group_a.name)
        self.ports.append(_Port(key, domain, effort, None if quasi else other, other if quasi else None, bond,
                                port_names, kind))

    # bonds ----------------------------------------------------------------------------------------

    def _bonds(self) -> tuple[list[Bond], list[Link]]:
        """Ports and powerBond groups become bonds of their domain; a quasi port takes its flow from a
        connection; displacement connections join the bond they serve; every other connection is a signal."""
        bonds: list[Bond] = []
        named: dict[str, list[Link]] = {}
        named_ports: dict[str, list[_Port]] = {}
        inputs: dict[tuple[str, str], str] = {}
        port_links = [link for port in self.ports for link in (port.effort, port.flow, port.displacement) if link]
        for link in self.links + port_links:
            for name in link.inputs:
                first = inputs.setdefault((link.target.name, name), link.key)
                if first != link.key:
                    self.problems.add(link.key, f"input {link.target.name}.{name} is already connected by {first}")
        free = [link for link in self.links if link.quantity != MIXED and link.bond is None]
        for link in self.links:
            if link.quantity != MIXED and link.bond is not None:
                named.setdefault(link.bond, []).append(link)
        for port in self.ports:
            _, flow, displacement = BOND_DOMAINS[port.domain]
            if port.bond is not None:
                named.setdefault(port.bond, []).extend(link for link in (port.effort, port.flow, port.displacement)
                                                       if link is not None)
                named_ports.setdefault(port.bond, []).append(port)
            elif port.flow is not None:
                bonds.append(Bond(port.key, port.effort, port.flow, points=port.names, domain=port.domain,
                                  why_no_displacement=f"an OSP {port.kind} exchanges no {displacement}, and no "
                                                      f"{displacement} connection joins it"))
            else:
                flow_link = self._quasi_flow(port, free)
                if flow_link is not None:
                    free.remove(flow_link)
                    bonds.append(Bond(f"{port.key} and {flow_link.key}", port.effort, flow_link,
                                      [port.displacement], points=port.names, domain=port.domain))
        for bond_name, links in named.items():
            bond = self._named_bond(bond_name, links, named_ports.get(bond_name, []))
            if bond is not None:
                bonds.append(bond)
        signals: list[Link] = []
        for link in free:
            domain, role = BOND_ROLES.get(link.quantity, (None, None))
            serves = [bond for bond in bonds if bond.domain == domain
                      and (bond.motion_side.name, bond.force_side.name) == (link.source.name, link.target.name)]
            if role == "displacement" and len(serves) == 1:
                serves[0].displacement.append(link)
            elif role == "displacement" and serves:
                self.problems.add(link.key, f"{link.text()}: {len(serves)} bonds join {link.source.name} (motion side) "
                                            f"to {link.target.name} (force side); cannot tell which one it serves")
            else:
                signals.append(link)
                if role in ("effort", "flow"):
                    self.notes.append(f"{link.key}: {link.text()} has no powerBond: a signal coupling, whose power "
                                      "zencosim does not monitor (mark the effort and the flow connection of a "
                                      "bond, e.g. its force and its velocity, with one powerBond name to make them a "
                                      "power bond)")
        for bond in bonds:
            if len(bond.displacement) > 1 and len(bond.force.outputs) > 1:
                self.notes.append(f"{bond.key}: the displacement components are its connections in document order")
        order = {id(link): i for i, link in enumerate(self.links)}
        signals.sort(key=lambda link: order[id(link)])  # document order
        return [bond for bond in bonds if check_bond(bond, self.problems)], signals

    def _quasi_flow(self, port: _Port, free: list[Link]) -> Link | None:
        """The flow of a quasi port's bond: the one connection of its domain's flow from the motion side to the
        force side that no powerBond claims; None with a problem when there is none, or several."""
        effort, flow, displacement = BOND_DOMAINS[port.domain]
        force_side, motion_side = port.effort.source.name, port.effort.target.name
        found = [link for link in free if link.quantity == flow
                 and (link.source.name, link.target.name) == (motion_side, force_side)]
        if len(found) == 1:
            self.notes.append(f"{port.key}: the {port.kind} exchanges the {effort} and the {displacement}; its bond's "
                              f"{flow} is {found[0].text()} ({found[0].key})")
            return found[0]
        port_kind = next(kind for kind, (domain, _, _) in PORTS.items() if domain == port.domain)
        flow_group = PORTS[port_kind][2]
        effort, flow, displacement = (q.replace("_", " ") for q in (effort, flow, displacement))
        if found:
            self.problems.add(port.key, f"{port.kind} {force_side}.{port.names[0]} -> {motion_side}.{port.names[1]}: "
                                        f"{len(found)} {flow} connections {motion_side} -> {force_side} "
                                        f"({', '.join(link.key for link in found)}); cannot tell which one is its "
                                        "bond's flow: mark it and the port with one powerBond name")
            return None
        self.problems.add(port.key, f"{port.kind} {force_side}.{port.names[0]} -> {motion_side}.{port.names[1]}: a "
                                    f"quasi port exchanges the {effort} and the {displacement} but no {flow}; "
                                    f"zencosim's power bond needs the {flow} (its residual power is {effort} x "
                                    f"{flow}): connect the {flow} output of {motion_side} to {force_side} too "
                                    f"({_a(flow_group)} group or a variable connection), or use {_a(port_kind)}")
        return None

    def _named_bond(self, bond_name: str, links: list[Link], ports: list[_Port]) -> Bond | None:
        """The bond of the connections sharing a powerBond name: one effort and one flow connection of one
        domain (by their units, or their port groups), and its displacement connections if any."""
        roles: dict[str, list[Link]] = {"effort": [], "flow": [], "displacement": []}
        domains = set()
        for link in links:
            domain, role = BOND_ROLES.get(link.quantity, (None, "other"))
            domains.add(domain)
            roles.setdefault(role, []).append(link)
        keys = " and ".join(dict.fromkeys(link.key for link in links))
        if len(domains) != 1 or None in domains or len(roles["effort"]) != 1 or len(roles["flow"]) != 1:
            found = ", ".join(link.text() for link in links)
            self.problems.add(keys, f"powerBond {bond_name!r}: expected one effort and one flow connection of one "
                                    "domain (force and velocity, torque and angular velocity, pressure and volume "
                                    "flow, or voltage and current, by the units of their variables), and its "
                                    f"displacement connections if any, got {found}")
            return None
        domain = domains.pop()
        effort = roles["effort"][0]
        names = next((port.names for port in ports if port.effort is effort), (None, None))
        displacement = BOND_DOMAINS[domain][2]
        return Bond(keys, effort, roles["flow"][0], list(roles["displacement"]), name=bond_name, points=names,
                    domain=domain, why_no_displacement=f"no {displacement} connection joins powerBond {bond_name!r}")


def _a(noun: str) -> str:
    return f"{'an' if noun[0].lower() in 'aeiou' else 'a'} {noun}"


def import_osp(path: Path, duration: float | None = None, algorithm: str | None = None,
               units: dict[str, dict[str, str]] | None = None) -> tuple[dict, list[str]]:
    """The scene document of the OSP system structure at ``path`` and the notes on its mapping (``algorithm``,
    ``units``: as :func:`~zencosim.manager.scene.imports.import_system` takes them); raises :class:`SceneError`
    listing whatever cannot be mapped."""
    return _Import(Path(path), duration, algorithm, units).run()
