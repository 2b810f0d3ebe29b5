"""SSP systems (a ``.ssp`` archive or a ``.ssd`` file, SSP 1.0) as zencosim scene documents.

The structure is read with fmpy (``fmpy.ssp.ssd.read_ssd``, which validates the SSD against the SSP 1.0
schema): components with their FMU ``source``, connectors, connections and parameter bindings (inline
``ssv:ParameterSet`` or ``.ssv`` files). What fmpy leaves out is read from the SSD here: the
``DefaultExperiment`` (``startTime``, ``stopTime``), the step sizes — the OSP annotations libcosim reads
(``ssc:Annotation type="com.opensimulationplatform"``: ``osp:Algorithm/osp:FixedStepAlgorithm
baseStepSize`` in the ``DefaultExperiment``, ``osp:StepSizeHint value`` in a component), else the FMUs'
own ``DefaultExperiment stepSize`` — a component's ``implementation`` and a connection's transformation.

SSP has no power-bond marker, so a bond is recognised by one rule, from the units the FMUs declare
(modelDescription, base-unit exponents): between two components F and M, the connections of effort
outputs of F to inputs of M (force [N], torque [N.m], pressure [Pa], voltage [V]) and of flow outputs of M
to inputs of F (velocity [m/s], angular velocity [rad/s], volume flow [m3/s], current [A]) of one domain
form one bond of that domain with force side F when there are equally many (n >= 1), with as many
displacement outputs of M to F (m, rad, m3, C) or none (``displacement = []``); the i-th of each, in
document order, is component i of a vector bond. Every other connection of real variables — another
quantity, no unit, counts that differ — is a ``signal`` coupling: the output's value copied into the
input. A ``ssc:LinearTransformation`` (factor, offset) maps to the signal coupling's ``factor`` and
``offset``, or on a bond's force connection to its ``force_factor`` (a force has no offset; a bond's
velocity and displacement are copied unchanged). A component coupled to nothing runs free and publishes
its outputs. Refused: nested systems, system connectors, signal dictionaries, parameter mappings,
Boolean, Integer and Enumeration mapping transformations (zencosim exchanges Real variables only).

FMUs inside a ``.ssp`` archive are read from it; the scene refers to them where the archive unpacks
beside it (``unzip NAME.ssp -d NAME``: ``NAME/resources/model.fmu``), and a note says so.
"""
from __future__ import annotations

import io
import posixpath
import zipfile
from pathlib import Path
from urllib.parse import unquote, urlparse
from urllib.request import url2pathname

from zencosim.manager.scene.imports import (
    BOND_DOMAINS,
    BOND_ROLES,
    MIXED,
    QUANTITIES,
    Bond,
    Component,
    Link,
    add_start,
    build_document,
    check_bond,
    check_transformation,
    children,
    document_path,
    link_quantity,
    local,
    number,
    orient,
    parse_xml,
    read_fmu,
    scene_name,
    set_timing,
    settle_duration,
    where,
)
from zencosim.manager.scene.load import SceneError
from zencosim.subsystems.params import Problems

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSD_MEMBER = "SystemStructure.ssd"
OSP_ANNOTATION = "com.opensimulationplatform"
FMU_TYPES = (None, "", "application/x-fmu-sharedlibrary")
PARAMETER_SET = (None, "", "application/x-ssp-parameter-set")


def _annotation(element, tag: str):
    """The ``osp:<tag>`` element of ``element``'s OSP annotation (libcosim's), or None."""
    for container in children(element, "Annotations"):
        for annotation in children(container, "Annotation"):
            if annotation.get("type") == OSP_ANNOTATION:
                for found in annotation.iter():
                    if isinstance(found.tag, str) and local(found) == tag:
                        return found
    return None


class _Import:
    """One SSP system being read; problems and notes collect as it goes."""

    def __init__(self, path: Path, duration: float | None, units: dict[str, dict[str, str]] | None = None) -> None:
        self.path = path
        self.units = units or {}  # the scene's units of FMU variables, by subsystem (import_system)
        self.directory = path.parent
        self.duration = duration
        self.archive = path.suffix.lower() == ".ssp"
        self.problems = Problems()
        self.notes: list[str] = []
        self.members: zipfile.ZipFile | None = None
        self.connectors: dict[str, dict[str, str]] = {}  # subsystem -> connector -> kind
        self.failed: set[str] = set()  # components that could not be read (reported where declared)

    def run(self) -> tuple[dict, list[str]]:
        ssd_bytes, container = self._read()
        root = parse_xml(ssd_bytes, SSD_MEMBER if self.archive else self.path.name, self.problems)
        if root is None:
            raise SceneError(str(self.path), self.problems)
        if local(root) != "SystemStructureDescription" or not str(root.tag).startswith(f"{{{SSD}}}"):
            raise self._refuse(where(root), f"expected an SSP 1.0 SystemStructureDescription (namespace {SSD})")
        if not self.archive:
            container = self._wrap(ssd_bytes, root)
        ssd = self._read_ssd(container)
        self._unread_parameters(root, container)
        systems = children(root, "System")
        if len(systems) != 1:
            raise self._refuse(where(root), "expected one System element")
        system_element = systems[0]
        base_step, component_steps, declared = self._experiment(root)
        components = self._components(ssd.system, system_element, component_steps)
        self._parameters(ssd, components)
        links = self._links(ssd.system, system_element, components)
        bonds, signals = self._bonds(links)
        members = list(components.values())
        base_step = self._settle_steps(base_step, members, where(root))
        if base_step is not None:
            set_timing(base_step, "DefaultExperiment: osp:FixedStepAlgorithm baseStepSize", members, self.problems)
        duration = None
        if base_step is not None and not self.problems:
            duration = settle_duration(self.duration, declared, "DefaultExperiment stopTime - startTime"
                                       if declared is not None else "the SSD's DefaultExperiment gives no stopTime",
                                       base_step, members, self.problems, self.notes)
        if self.problems:
            raise SceneError(str(self.path), self.problems)
        name = root.get("name") or ssd.system.name or self.path.stem
        description = f"imported from the SSP {self.path.name}"
        if ssd.system.description:
            description += f": {ssd.system.description}"
        return build_document(name, description, base_step, duration, members, bonds, self.notes, signals), \
            self.notes

    def _refuse(self, key: str, reason: str) -> SceneError:
        self.problems.add(key, reason)
        return SceneError(str(self.path), self.problems)

    # reading ------------------------------------------------------------------------------------

    def _read(self) -> tuple[bytes, bytes]:
        """The SSD's text and the archive fmpy reads it from (a .ssd file: wrapped later)."""
        try:
            data = self.path.read_bytes()
        except OSError as error:
            raise self._refuse("file", f"cannot read: {error.strerror or error}") from None
        if not self.archive:
            return data, b""
        try:
            self.members = zipfile.ZipFile(io.BytesIO(data))
            return self.members.read(SSD_MEMBER), data
        except zipfile.BadZipFile as error:
            raise self._refuse("file", f"not an SSP archive (a zip file): {error}") from None
        except KeyError:
            raise self._refuse("file", f"the archive holds no {SSD_MEMBER}") from None
        except Exception as error:  # noqa: BLE001 (a damaged member: zlib, CRC, …)
            raise self._refuse("file", f"cannot read {SSD_MEMBER} from the archive: {error}") from None

    def _wrap(self, ssd_bytes: bytes, root) -> bytes:
        """A .ssd file, and the parameter files it references, as the archive fmpy's reader expects."""
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w") as archive:
            archive.writestr(SSD_MEMBER, ssd_bytes)
            for element in root.iter():
                if not isinstance(element.tag, str) or local(element) not in ("ParameterBinding", "ParameterMapping",
                                                                             "SignalDictionary"):
                    continue
                source = element.get("source")
                if not source:
                    continue
                file = self.directory / unquote(source)
                try:
                    archive.writestr(source, file.read_bytes())
                except OSError:
                    self.problems.add(where(element), f"source {source!r}: no file at {file}")
        return buffer.getvalue()

    def _unread_parameters(self, root, container: bytes) -> None:
        """A note on each element of a parameter set's ``Parameters`` that is no ``ssv:Parameter``, which fmpy's
        reader (and so the import) passes over: in the SSD, or in a parameter file it binds."""
        trees = [(root, "")]
        with zipfile.ZipFile(io.BytesIO(container)) as archive:
            members = set(archive.namelist())
            for binding in root.iter(f"{{{SSD}}}ParameterBinding"):
                source = binding.get("source")
                if source in members:
                    tree = parse_xml(archive.read(source), source, Problems())  # fmpy has read it already
                    trees += [(tree, f"{source}: ")] if tree is not None else []
        for tree, prefix in trees:
            for parameters in tree.iter(f"{{{SSV}}}Parameters"):
                for child in children(parameters):
                    if child.tag != f"{{{SSV}}}Parameter":
                        self.notes.append(f"{where(child, prefix)}: an element of Parameters that is no ssv:Parameter "
                                          "is not read (as fmpy reads a parameter set): ignored")

    def _read_ssd(self, container: bytes):
        try:
            from fmpy.ssp.ssd import read_ssd
        except ImportError:
            raise self._refuse("file", "reading SSP needs fmpy (pip install fmpy)") from None
        if self.problems:
            raise SceneError(str(self.path), self.problems)
        try:
            return read_ssd(io.BytesIO(container), validate=True)
        except Exception as error:  # noqa: BLE001 (fmpy raises plain exceptions for schema violations)
            lines = str(error).strip().splitlines() or [type(error).__name__]
            more = f" (and {len(lines) - 4} more lines)" if len(lines) > 4 else ""
            raise self._refuse(SSD_MEMBER if self.archive else self.path.name,
                               "not a valid SSP 1.0 system structure: " + " ".join(lines[:4]) + more) from None

    def _experiment(self, root) -> tuple[float | None, dict[str, float], float | None]:
        """The OSP base step, the components' OSP step size hints and the declared duration."""
        base_step, declared = None, None
        for experiment in children(root, "DefaultExperiment"):
            key = where(experiment)
            start = number(experiment.get("startTime", "0"), key, "startTime [s]", self.problems)
            if start:
                self.problems.add(key, f"startTime {start!r} s: zencosim starts every run, and sets up its FMUs, at "
                                       "t = 0 s")
            if experiment.get("stopTime") is not None:
                stop = number(experiment.get("stopTime"), key, "stopTime [s]", self.problems)
                if stop is not None and stop <= (start or 0.0):
                    self.problems.add(key, f"stopTime {stop!r} s: expected a time after startTime")
                elif stop is not None:
                    declared = stop - (start or 0.0)
            algorithm = _annotation(experiment, "Algorithm")
            if algorithm is not None:
                fixed = [a for a in children(algorithm) if local(a) == "FixedStepAlgorithm"]
                if not fixed:
                    self.problems.add(where(algorithm), "OSP algorithm: expected FixedStepAlgorithm; zencosim steps "
                                                        "at a fixed macro step")
                else:
                    base_step = number(fixed[0].get("baseStepSize"), where(fixed[0]), "baseStepSize [s]",
                                       self.problems, positive=True)
        steps = {}
        for system in children(root, "System"):
            for element in (e for elements in children(system, "Elements") for e in children(elements, "Component")):
                hint = _annotation(element, "StepSizeHint")
                if hint is not None and element.get("name"):
                    step = number(hint.get("value"), where(hint), "StepSizeHint value [s]", self.problems,
                                  positive=True)
                    if step is not None:
                        steps[element.get("name")] = step
        return base_step, steps, declared

    def _settle_steps(self, base_step: float | None, components: list[Component], key: str) -> float | None:
        """Each component's step (its OSP hint, else the base step, else its FMU's DefaultExperiment stepSize)
        and the base step (the OSP annotation's, else the smallest component step)."""
        if not components:
            return base_step
        for component in components:
            if component.step is not None:
                continue
            if base_step is not None:
                component.step = base_step
                self.notes.append(f"subsystems.{component.name}.micro_step = {base_step!r} s: {component.key} has no "
                                  "osp:StepSizeHint; the base step, as libcosim steps it")
            elif component.fmu.default_step is not None:
                component.step = component.fmu.default_step
                self.notes.append(f"subsystems.{component.name}.micro_step = {component.step!r} s: {component.key} "
                                  "has no osp:StepSizeHint; its FMU's DefaultExperiment stepSize")
        if base_step is not None:
            return base_step
        missing = [c.name for c in components if c.step is None]
        if missing and self.problems:  # a refused base step annotation, reported where it is
            return None
        if missing:
            self.problems.add(key, f"no step size for {', '.join(missing)}: add the OSP annotation libcosim reads "
                                   "(DefaultExperiment: ssc:Annotation type=\"com.opensimulationplatform\" holding "
                                   "osp:Algorithm/osp:FixedStepAlgorithm baseStepSize=\"…\"; a component: "
                                   "osp:StepSizeHint value=\"…\"), or give the FMUs a DefaultExperiment stepSize")
            return None
        base_step = min(c.step for c in components)
        self.notes.append(f"manager.macro_step = {base_step!r} s: no base step annotation; the smallest component "
                          "step")
        return base_step

    # components ---------------------------------------------------------------------------------

    def _components(self, system, system_element, steps: dict[str, float]) -> dict[str, Component]:
        from fmpy.ssp.ssd import Component as SspComponent
        elements = {e.get("name"): e for elements in children(system_element, "Elements")
                    for e in children(elements, "Component")}
        components: dict[str, Component] = {}
        used: set[str] = set()
        for element in system.elements:
            if not isinstance(element, SspComponent):
                kind = type(element).__name__
                self.problems.add(f"{kind} {element.name!r}", f"{'nested systems' if kind == 'System' else kind + 's'} "
                                                              "are not supported: import a flat system of FMUs")
                continue
            xml = elements.get(element.name)
            key = where(xml) if xml is not None else f"Component {element.name!r}"
            if element.name in components:
                self.problems.add(key, f"a second component named {element.name!r}")
                continue
            if element.type not in FMU_TYPES:
                self.problems.add(key, f"component type {element.type!r}: only FMUs (application/x-fmu-sharedlibrary) "
                                       "are supported")
                continue
            if xml is not None and xml.get("implementation") == "ModelExchange":
                self.problems.add(key, "implementation ModelExchange: a co-simulation system steps Co-Simulation FMUs")
                continue
            component = self._component(element, key, steps.get(element.name), used)
            if component is not None:
                components[element.name] = component
            else:
                self.failed.add(element.name)
        if system.signalDictionaries:
            self.problems.add("SignalDictionaries", "signal dictionaries are not supported")
        if not components and not self.problems:
            self.problems.add("System", "expected at least one component")
        return components

    def _component(self, element, key: str, step: float | None, used: set[str]) -> Component | None:
        source = element.source or ""
        parsed = urlparse(source)
        data: Path | bytes
        if parsed.scheme == "file":
            file = Path(url2pathname(parsed.path))
            place = document_path(file, self.directory)
        elif parsed.scheme and len(parsed.scheme) > 1:
            self.problems.add(key, f"source {source!r}: only FMU files are supported (a relative path or a file: URI), "
                                   f"not {parsed.scheme}: URIs")
            return None
        elif self.archive:
            stem = self.path.stem
            place = posixpath.normpath(posixpath.join(stem, unquote(source)))
            file = self.directory / place
        else:
            file = self.directory / unquote(source)
            place = document_path(file, self.directory)
        if self.archive and parsed.scheme != "file" and place.startswith(f"{self.path.stem}/"):
            member = place[len(self.path.stem) + 1:]
            try:
                data = self.members.read(member)
            except KeyError:
                self.problems.add(key, f"source {source!r}: no FMU file {member} in {self.path.name}")
                return None
            except Exception as error:  # noqa: BLE001 (a damaged member: zlib, CRC, …)
                self.problems.add(key, f"source {source!r}: cannot read {member} from {self.path.name}: {error}")
                return None
            inside = (f"{place!r}: the FMU is {member} inside {self.path.name}; unpack the archive beside the scene "
                      f"(unzip {self.path.name} -d {self.path.stem})")
        elif not file.is_file():
            self.problems.add(key, f"source {source!r}: no FMU file at {file}")
            return None
        else:
            data, inside = file, None
        fmu, reason = read_fmu(data, posixpath.basename(place))
        if fmu is None:
            self.problems.add(key, f"FMU {source}: {reason}")
            return None
        name = scene_name(element.name or "component", used, "the component", self.notes)
        component = Component(name, key, fmu, place, step, units=dict(self.units.get(name, {})))
        if inside is not None:
            self.notes.append(f"subsystems.{component.name}.fmu = {inside}")
        self.connectors[component.name] = {c.name: c.kind for c in element.connectors}
        return component

    def _parameters(self, ssd, components: dict[str, Component]) -> None:
        """Parameter bindings of the components, then of the system (which take precedence), as start values."""
        units = {u.name: u for u in ssd.units}
        for raw_name, component in components.items():
            element = next(e for e in ssd.system.elements if e.name == raw_name)
            for binding in element.parameterBindings:
                for name, parameter in self._bound(binding, component.key):
                    self._start(component, name, parameter, units, component.key)
        for binding in ssd.system.parameterBindings:
            for name, parameter in self._bound(binding, "System ParameterBinding"):
                owner = next((raw for raw in components if name.startswith(f"{raw}.")), None)
                if owner is None:
                    self.notes.append(f"System ParameterBinding: parameter {name!r} names no component variable; "
                                      "ignored, as SSP prescribes")
                    continue
                self._start(components[owner], name[len(owner) + 1:], parameter, units, "System ParameterBinding")

    def _bound(self, binding, key: str):
        if binding.type not in PARAMETER_SET:
            self.problems.add(key, f"ParameterBinding of type {binding.type!r}: only parameter sets are supported")
            return
        if binding.parameterMapping:
            self.problems.add(key, "ParameterMapping is not supported: name the FMU variables in the parameter set")
            return
        for parameter_set in binding.parameterValues:
            for parameter in parameter_set.parameters:
                yield (binding.prefix or "") + (parameter.name or ""), parameter

    def _start(self, component: Component, name: str, parameter, units: dict, key: str) -> None:
        if name not in component.fmu.variables:
            self.notes.append(f"{key}: {component.name} has no variable {name!r}; its parameter is ignored, as SSP "
                              "prescribes")
            return
        unit = units.get(parameter.unit) if parameter.unit else None
        value = parameter.value
        if unit is not None and (unit.factor != 1.0 or unit.offset != 0.0) and parameter.type == "Real":
            given = number(value, f"{key}: parameter {name!r}", f"the value of {name}", self.problems)
            if given is None:
                return
            value = repr(unit.factor * given + unit.offset)
            self.notes.append(f"{key}: parameter {name!r} = {parameter.value} {parameter.unit} is {value} in SI "
                              f"(factor {unit.factor:g}, offset {unit.offset:g}): a scene's start values are SI, "
                              "converted into the FMU's own unit when it is set")
        add_start(component, name, parameter.type or "?", value, f"{key}: parameter {name!r}", self.problems)

    # connections and bonds --------------------------------------------------------------------

    def _links(self, system, system_element, components: dict[str, Component]) -> list[Link]:
        elements = [c for connections in children(system_element, "Connections")
                    for c in children(connections, "Connection")]
        links = []
        for connection, xml in zip(system.connections, elements):
            ends = f"{connection.startElement}.{connection.startConnector} -> " \
                   f"{connection.endElement}.{connection.endConnector}"
            key = f"Connection {ends} (line {xml.sourceline})"
            factor, offset = self._transformation(xml, key)
            if factor is None:
                continue
            if connection.startElement is None or connection.endElement is None:
                self.problems.add(key, "connections to the system's own connectors are not supported: zencosim "
                                       "couples FMU components to each other")
                continue
            ends_found = []
            for element, connector in ((connection.startElement, connection.startConnector),
                                       (connection.endElement, connection.endConnector)):
                if element not in components:
                    if element not in self.failed:
                        self.problems.add(key, f"unknown component {element!r}")
                    break
                component = components[element]
                if connector not in self.connectors[component.name]:
                    self.problems.add(key, f"component {element!r} declares no connector {connector!r}")
                    break
                ends_found.append((component, connector))
            if len(ends_found) != 2:
                continue
            (a, a_name), (b, b_name) = ends_found
            oriented = orient(key, a, [a_name], b, [b_name], self.problems)
            if oriented is None:
                continue
            for component, name in ends_found:
                kind, causality = self.connectors[component.name][name], component.fmu.variables[name].causality
                if kind != causality:
                    self.problems.add(key, f"connector {component.name}.{name} is of kind {kind!r}, its FMU variable "
                                           f"of causality {causality!r}")
            source, outputs, target, inputs = oriented
            quantity = link_quantity(key, source, outputs, target, inputs, self.problems)
            link = Link(key, source, outputs, target, inputs, quantity, factor=factor, offset=offset)
            if check_transformation(link, self.problems):
                links.append(link)
        return links

    def _transformation(self, xml, key: str) -> tuple[float | None, float]:
        """A connection's ``ssc:LinearTransformation`` as (factor, offset) ((1, 0) without one); (None, 0)
        with a problem for what zencosim cannot apply."""
        factor, offset = 1.0, 0.0
        for child in children(xml):
            kind = local(child)
            if kind in ("ConnectionGeometry", "Annotations"):
                continue
            if kind == "LinearTransformation":
                factor = number(child.get("factor", "1"), key, "the LinearTransformation factor", self.problems)
                offset = number(child.get("offset", "0"), key, "the LinearTransformation offset", self.problems)
                if factor is None or offset is None:
                    return None, 0.0
            elif kind in ("BooleanMappingTransformation", "IntegerMappingTransformation",
                          "EnumerationMappingTransformation"):
                self.problems.add(key, f"{kind}: zencosim exchanges Real variables only (Boolean, Integer and "
                                       "Enumeration connections are not exchanged yet)")
                return None, 0.0
            else:
                self.problems.add(key, f"unknown element {kind} in a Connection")
                return None, 0.0
        return factor, offset

    def _bonds(self, links: list[Link]) -> tuple[list[Bond], list[Link]]:
        """The SSP bond rule: per (force side, motion side, domain), as many effort connections one way as flow
        connections the other, and as many displacement connections as those or none; every other connection
        is a signal."""
        pairs: dict[tuple[str, str, str], dict[str, list[Link]]] = {}
        signals: list[Link] = []
        seen_inputs: dict[tuple[str, str], str] = {}
        for link in links:
            first = seen_inputs.setdefault((link.target.name, link.inputs[0]), link.key)
            if first != link.key:
                self.problems.add(link.key, f"input {link.target.name}.{link.inputs[0]} is already connected by "
                                            f"{first}")
            if link.quantity == MIXED:
                continue
            if link.quantity not in BOND_ROLES:
                signals.append(link)
                continue
            domain, role = BOND_ROLES[link.quantity]
            sides = (link.source.name, link.target.name) if role == "effort" else (link.target.name, link.source.name)
            group = pairs.setdefault((*sides, domain), {"effort": [], "flow": [], "displacement": []})
            group[role].append(link)
        bonds = []
        for (force_side, motion_side, domain), found in pairs.items():
            counts = {role: len(group) for role, group in found.items()}
            keys = " and ".join(link.key for group in found.values() for link in group)
            effort, flow, displacement = BOND_DOMAINS[domain]
            if counts["effort"] != counts["flow"] or counts["displacement"] not in (0, counts["effort"]) \
                    or not counts["effort"]:
                units = {q: QUANTITIES[q][0] for q in (effort, flow, displacement)}
                self.notes.append(f"{keys}: connections between {force_side} and {motion_side} form no power bond "
                                  f"({counts['effort']} {effort} [{units[effort]}] {force_side} -> {motion_side}, "
                                  f"{counts['flow']} {flow} [{units[flow]}] and {counts['displacement']} "
                                  f"{displacement} [{units[displacement]}] {motion_side} -> {force_side}; a bond has "
                                  f"as many of each, or no {displacement}): signal couplings, whose power zencosim "
                                  "does not monitor")
                signals += [link for group in found.values() for link in group]
                continue
            if not self._plain_bond(found):
                continue
            if counts["effort"] > 1:
                self.notes.append(f"couplings: {counts['effort']} {effort} connections {force_side} -> {motion_side} "
                                  "form one vector bond; components in document order")
            bond = Bond(keys, _joined(found["effort"]), _joined(found["flow"]), list(found["displacement"]),
                        domain=domain, why_no_displacement=f"no {displacement} connection {motion_side} -> "
                                                           f"{force_side}")
            if check_bond(bond, self.problems):
                bonds.append(bond)
        order = {id(link): i for i, link in enumerate(links)}
        signals.sort(key=lambda link: order[id(link)])  # document order
        return bonds, signals

    def _plain_bond(self, found: dict[str, list[Link]]) -> bool:
        """A bond's connections carry its force, velocity and displacement as they are: only its force may be
        scaled (the coupling's ``force_factor``, one for all its components), and none offset."""
        ok = True
        for role, group in found.items():
            for link in group:
                if role != "effort" and (link.factor != 1.0 or link.offset != 0.0):
                    self.problems.add(link.key, f"LinearTransformation (factor {link.factor:g}, offset "
                                                f"{link.offset:g}) on the {link.quantity} of a power bond: zencosim "
                                                "copies a bond's velocity and displacement unchanged (only its force "
                                                "may be scaled, force_factor)")
                    ok = False
                elif link.offset != 0.0:
                    self.problems.add(link.key, f"LinearTransformation offset {link.offset:g} on the {link.quantity} "
                                                "of a power bond: a bond's force has no offset (a factor is its "
                                                "force_factor)")
                    ok = False
        factors = {link.factor for link in found["effort"]}
        if ok and len(factors) > 1:
            self.problems.add(" and ".join(link.key for link in found["effort"]),
                              f"the force components of one vector bond have different LinearTransformation factors "
                              f"({', '.join(f'{f:g}' for f in sorted(factors))}); zencosim scales a bond's force by "
                              "one force_factor")
            ok = False
        return ok


def _joined(links: list[Link]) -> Link:
    """Scalar connections of one direction as one vector link, in document order."""
    first = links[0]
    return Link(" and ".join(link.key for link in links), first.source,
                tuple(n for link in links for n in link.outputs), first.target,
                tuple(n for link in links for n in link.inputs), first.quantity, factor=first.factor)


def import_ssp(path: Path, duration: float | None = None,
               units: dict[str, dict[str, str]] | None = None) -> tuple[dict, list[str]]:
    """The scene document of the SSP system at ``path`` (``.ssp`` or ``.ssd``) and the notes on its mapping
    (``units``: as :func:`~zencosim.manager.scene.imports.import_system` takes them); raises :class:`SceneError`
    listing whatever cannot be mapped."""
    return _Import(Path(path), duration, units).run()
