"""Import the system descriptions co-simulation users already have, as zencosim scene documents.

:func:`import_system` reads an OSP system structure (libcosim's ``OspSystemStructure.xml`` with the OSP
Interface Specification's variable groups: :mod:`.osp`) or an SSP system (a ``.ssp`` archive or a
``.ssd`` file: :mod:`.ssp`) and returns a scene document, a dict that ``tomli_w`` writes and
``manager.scene.load.scene_from_text`` reads, together with notes: every assumption the mapping made.
Each FMU becomes a ``model = "fmu"`` subsystem; each power bond (a force one way, the velocity and the
displacement of the point it acts on the other way; in another domain its effort, flow and displacement:
torque, angular velocity, angle; pressure, volume flow, volume; voltage, current, charge) becomes a
``force_displacement`` coupling of its ``domain`` whose force side is the FMU that outputs the effort;
every other connection of real variables becomes a ``signal`` coupling (the output's value copied into the
input); an FMU coupled to nothing runs free and publishes its outputs. Whatever cannot be mapped (an
algorithm other than fixed step, a connection of Integer or Boolean variables, an input connected twice, a
variable group type zencosim does not know, a quasi port without its flow, a step size that is not a whole
number of base steps, a missing FMU, a unit zencosim cannot read) raises
:class:`~zencosim.manager.scene.load.SceneError` naming the file, the element and what is wrong; nothing is
dropped silently. FMU paths in the document are relative to the imported file's directory, where the
scene is meant to be written. The mapping, and the bond rules of each format: docs/system-imports.md.

What both formats share is here: the FMUs and the quantities of their variables (from the units of their
modelDescription), start values, the timing (base step, communication ratios, duration), bonds and the
document built from them.
"""
from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zencosim.manager.scene.load import SceneError, refuse_irregular
from zencosim.manager.scene.times import NotATime, nanoseconds
from zencosim.subsystems.params import Problems
from zencosim.subsystems.units import BASE, Exponents, UnitError, describe, exponents, replaceable, unit_contradiction

QUANTITIES: dict[str, tuple[str, Exponents]] = {  # quantity -> (SI unit, base-unit exponents)
    name: (unit, exponents(unit)) for name, unit in (
        ("force", "N"), ("velocity", "m/s"), ("displacement", "m"), ("energy", "J"), ("torque", "N.m"),
        ("angular_velocity", "rad/s"), ("angle", "rad"), ("pressure", "Pa"), ("volume_flow", "m3/s"),
        ("volume", "m3"), ("voltage", "V"), ("current", "A"), ("charge", "C"))}
# the quantities of a bond's effort, flow and displacement in each domain (zencosim.subsystems.ports.DOMAINS)
BOND_DOMAINS: dict[str, tuple[str, str, str]] = {
    "translational": ("force", "velocity", "displacement"),
    "rotational": ("torque", "angular_velocity", "angle"),
    "hydraulic": ("pressure", "volume_flow", "volume"),
    "electrical": ("voltage", "current", "charge"),
}
BOND_ROLES: dict[str, tuple[str, str]] = {  # quantity -> (domain, "effort" | "flow" | "displacement")
    quantity: (domain, role) for domain, quantities in BOND_DOMAINS.items()
    for role, quantity in zip(("effort", "flow", "displacement"), quantities)}
_TORQUE_NAMES = {"N.m", "N*m", "N m", "Nm", "m.N"}
REAL_TYPES = ("Real", "Float64")
MIXED = "mixed quantities"  # a link whose variables disagree (reported where found)
DEFAULT_DURATION = 10.0  # [s] when neither the file nor the caller gives one


ALGORITHMS = ("fixed",)  # what a user may ask a system's algorithm to be replaced with (``manager.algorithm``)


def import_system(path: Path, duration: float | None = None, algorithm: str | None = None,
                  input_table: str | None = None, units: dict[str, dict[str, str]] | None = None
                  ) -> tuple[dict, list[str]]:
    """The scene document of the system described at ``path`` and the notes on its mapping.

    ``.xml``: an OSP system structure; ``.ssp`` or ``.ssd``: an SSP system; ``.fmu``: one FMU run alone
    (``input_table``: a CSV file of its input values over time, :mod:`.fmu`). ``duration`` [s] is the
    simulated time (default: the file's end time, else 10 s; rounded up to a whole number of
    communication periods). ``algorithm = "fixed"`` runs an OSP system whose algorithm zencosim does not
    have (``ecco``) at its base step with the fixed-step algorithm. ``units``: the scene's units of FMU
    variables, ``{subsystem: {variable: SI unit}}`` (``--set subsystems.<name>.units.<variable>=UNIT``), which
    give a connection's quantity where an FMU declares none, or a dimensionless one, which they replace
    (:func:`stated_quantity`). Raises :class:`SceneError` listing everything that cannot be mapped.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    refuse_irregular(path, "file")
    if algorithm is not None and algorithm not in ALGORITHMS:
        raise refusal(path, "manager.algorithm", f"expected one of {', '.join(ALGORITHMS)}, got {algorithm!r}")
    if input_table is not None and suffix != ".fmu":
        raise refusal(path, "input", "an input table belongs to a run of one FMU (zencosim run model.fmu --input "
                                     "table.csv); a system's inputs are fed by its connections")
    if suffix == ".fmu":
        from zencosim.manager.scene.imports.fmu import import_fmu
        return import_fmu(path, duration, input_table)
    if suffix == ".xml":
        from zencosim.manager.scene.imports.osp import import_osp
        return import_osp(path, duration, algorithm, units or {})
    if suffix in (".ssp", ".ssd"):
        from zencosim.manager.scene.imports.ssp import import_ssp
        return import_ssp(path, duration, units or {})
    raise refusal(path, "file", f"expected an OSP system structure (.xml) or an SSP system (.ssp, .ssd), "
                                f"got {path.name!r}")


def refusal(path: Path, key: str, reason: str) -> SceneError:
    """A :class:`SceneError` with one problem."""
    problems = Problems()
    problems.add(key, reason)
    return SceneError(str(path), problems)


# XML ------------------------------------------------------------------------------------------------

def parse_xml(data: bytes, label: str, problems: Problems) -> Any:
    """The root element of an XML document (lxml, no entities, no network), or None with a problem."""
    try:
        from lxml import etree
    except ImportError:  # lxml comes with fmpy
        problems.add(label, "reading system descriptions needs fmpy (pip install fmpy), which brings lxml")
        return None
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_comments=True, remove_pis=True,
                             huge_tree=False)
    try:
        return etree.fromstring(data, parser)
    except etree.XMLSyntaxError as error:
        problems.add(label, f"not well-formed XML: {error}")
    except ValueError as error:  # e.g. an encoding declaration lxml refuses
        problems.add(label, f"cannot be read as XML: {error}")
    return None


def local(element: Any) -> str:
    """An element's tag without its namespace."""
    tag = element.tag
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def children(element: Any, name: str | None = None) -> list:
    """The child elements (no comments), those with local name ``name`` if given."""
    return [c for c in element if isinstance(c.tag, str) and (name is None or local(c) == name)]


def note_unread(element: Any, read: tuple[str, ...], key: str, notes: list[str]) -> None:
    """A note naming the attributes of ``element`` that the import does not read (``read``: those it does), which
    change nothing in the scene: a value's ``unit``, say, is not converted."""
    unread = [f"{name.rsplit('}', 1)[-1]}={value!r}" for name, value in element.attrib.items() if name not in read]
    if unread:
        notes.append(f"{key}: {local(element)} {', '.join(unread)} not read (zencosim reads {', '.join(read)}): "
                     "ignored, the value is used as written")


def where(element: Any, prefix: str = "") -> str:
    """The key naming an element in problems: its tag, its name and its line."""
    name = element.get("name")
    named = f" {name!r}" if name is not None else ""
    line = f" (line {element.sourceline})" if element.sourceline else ""
    return f"{prefix}{local(element)}{named}{line}"


def number(text: str | None, key: str, what: str, problems: Problems, positive: bool = False) -> float | None:
    """A finite float from XML text, or None with a problem."""
    try:
        value = float((text or "").strip())
    except ValueError:
        problems.add(key, f"expected {what} as a number, got {text!r}")
        return None
    if not math.isfinite(value) or (positive and value <= 0.0):
        problems.add(key, f"expected {what} as a {'positive' if positive else 'finite'} number, got {text!r}")
        return None
    return value


# FMUs and the quantities of their variables --------------------------------------------------------

@dataclass(frozen=True)
class UnitDefinition:
    """A unit as an FMU, an OSP model description or an SSD defines it."""

    exponents: Exponents | None  # None: the definition has no BaseUnit (read the name)
    factor: float = 1.0
    offset: float = 0.0


def unit_exponents(unit: str, definitions: dict[str, UnitDefinition],
                   converted: bool = True) -> tuple[Exponents | None, str | None]:
    """The SI base-unit exponents of ``unit`` (its definition, else its name read as a coherent SI unit
    such as ``N``, ``m/s`` or ``kg.m/s2``), or (None, why not). A definition with a factor or an offset
    (``mm``, ``bar``, ``degC``) is accepted when ``converted``: the FMU's own unit definitions, which
    zencosim converts at the FMU's boundary (SI = factor * value + offset); a system description's unit
    with a factor or an offset is not (``converted = False``), unless the FMU defines the same one."""
    definition = definitions.get(unit)
    if definition is not None and definition.exponents is not None:
        if not converted and (definition.factor != 1.0 or definition.offset != 0.0):
            return None, (f"unit {unit!r} is not SI (factor {definition.factor:g}, offset {definition.offset:g}) and "
                          "the FMU does not declare it for this variable: zencosim converts the units an FMU "
                          "defines for its own variables, at its boundary; declare it in the FMU or give an SI unit")
        return definition.exponents, None
    try:
        return exponents(unit), None
    except UnitError:
        return None, (f"unit {unit!r} is neither defined with base-unit exponents nor a coherent SI unit "
                      f"(e.g. N, m, m/s, J): zencosim cannot tell its quantity")


def unit_definition(component: "Component", name: str) -> UnitDefinition | None:
    """The FMU's definition of the unit of its variable ``name`` (None: no unit, or a unit name without
    definition, which is SI)."""
    variable = component.fmu.variables.get(name)
    unit = variable_unit(variable) if variable is not None else None
    return component.fmu.units.get(unit) if unit else None


def converted(definition: UnitDefinition | None) -> bool:
    """Whether values in this unit are converted at the FMU's boundary (a factor or an offset)."""
    return definition is not None and (definition.factor != 1.0 or definition.offset != 0.0)


def quantity_of(found: Exponents, torque: bool = False) -> str:
    """A name of :data:`QUANTITIES` (``force``, ``velocity``, ``angle``, …), or the exponents written out. A
    torque and an energy share their exponents: ``torque`` says which (the unit's name or the variable's
    declared quantity, :func:`is_torque`)."""
    if torque and found == QUANTITIES["torque"][1]:
        return "torque"
    for name, (_, dims) in QUANTITIES.items():
        if dims == found and name != "torque":
            return name
    return describe(found) if any(found) else "dimensionless"


def is_torque(unit: str | None, variable: Any = None) -> bool:
    """Whether a unit of N.m (J's exponents) is a torque: by its name (``N.m``, ``Nm``, …) or the variable's
    declared quantity (``Torque``, ``Moment``)."""
    named = unit is not None and unit.replace(" ", "") in {u.replace(" ", "") for u in _TORQUE_NAMES}
    declared = (getattr(variable, "quantity", None) or "").lower()
    return named or "torque" in declared or "moment" in declared


def same_quantity(found: str | None, expected: str) -> bool:
    """Whether a link's quantity from units is the ``expected`` one (a torque in J's exponents counts)."""
    if found == expected:
        return True
    return found in QUANTITIES and QUANTITIES[found][1] == QUANTITIES[expected][1]


@dataclass
class Fmu:
    """What an import needs of an FMU's modelDescription."""

    label: str  # the file, for messages
    model_name: str
    variables: dict[str, Any]  # fmpy ModelVariable by name
    units: dict[str, UnitDefinition]
    default_step: float | None = None  # its DefaultExperiment stepSize [s]
    description: Any = None  # fmpy's ModelDescription, as read (a lone FMU's run takes its experiment)


def read_fmu(source: Path | bytes, label: str) -> tuple[Fmu | None, str | None]:
    """The FMU at ``source`` (a path, or the bytes of an FMU inside an archive), or (None, why not)."""
    try:
        from fmpy import read_model_description
    except ImportError:
        return None, "reading FMUs needs fmpy (pip install fmpy)"
    try:
        model = read_model_description(io.BytesIO(source) if isinstance(source, bytes) else str(source),
                                       validate=False)
    except Exception as error:  # noqa: BLE001 (fmpy raises any exception for a malformed FMU)
        return None, f"its modelDescription.xml cannot be read: {type(error).__name__}: {error}"
    version = str(model.fmiVersion)
    if version not in ("2.0",) and not version.startswith("3."):
        return None, f"FMI {version}; zencosim runs FMI 2.0 and 3.0 FMUs"
    if model.coSimulation is None:
        return None, "has no Co-Simulation interface (a co-simulation system steps Co-Simulation FMUs)"
    units = {}
    for unit in model.unitDefinitions:
        base = unit.baseUnit
        units[unit.name] = UnitDefinition(None if base is None else tuple(int(getattr(base, b)) for b in BASE),
                                          1.0 if base is None else float(base.factor),
                                          0.0 if base is None else float(base.offset))
    experiment = model.defaultExperiment
    try:
        default_step = float(experiment.stepSize) if experiment is not None and experiment.stepSize else None
    except ValueError:
        default_step = None
    if default_step is not None and not (math.isfinite(default_step) and default_step > 0.0):
        default_step = None
    return Fmu(label, str(model.modelName), {v.name: v for v in model.modelVariables}, units, default_step,
               model), None


def variable_unit(variable: Any) -> str | None:
    """The unit an FMU declares for a variable (its own, else its type's)."""
    declared = variable.declaredType.unit if variable.declaredType is not None else None
    return variable.unit or declared


@dataclass
class Component:
    """An FMU subsystem of the system being imported."""

    name: str  # its subsystem name in the scene
    key: str  # the element that declares it, for problems
    fmu: Fmu
    path: str  # the FMU's path in the document, relative to the scene's directory
    step: float | None  # its doStep size = its communication step [s] (None: not settled yet)
    start: dict[str, float] = field(default_factory=dict)
    comm_ratio: int = 1
    units: dict[str, str] = field(default_factory=dict)  # the scene's units of its variables (import_system)


def check_variable(component: Component, name: str, key: str, problems: Problems) -> Any:
    """The FMU variable ``name`` of ``component`` as a real variable, or None with a problem."""
    variable = component.fmu.variables.get(name)
    if variable is None:
        problems.add(key, f"{component.name} ({component.fmu.label}) has no variable {name!r}")
        return None
    if variable.type not in REAL_TYPES:
        problems.add(key, f"{component.name}.{name} is {variable.type}: zencosim exchanges Real variables only "
                          "(Integer, Boolean, Enumeration and String connections are not exchanged yet)")
        return None
    return variable


def add_start(component: Component, name: str, kind: str, value: str | None, key: str, problems: Problems) -> None:
    """A start value from the system description (``kind`` Real, Integer, …), checked against the FMU."""
    variable = component.fmu.variables.get(name)
    if variable is None:
        problems.add(key, f"{component.name} ({component.fmu.label}) has no variable {name!r}")
        return
    if kind != "Real" or variable.type not in REAL_TYPES:
        problems.add(key, f"start value of type {kind} for {component.name}.{name} ({variable.type}): zencosim sets "
                          "real start values only")
        return
    if variable.causality == "output" or (variable.causality not in ("parameter", "input")
                                          and variable.initial not in ("exact", "approx")):
        problems.add(key, f"{component.name}.{name} ({variable.causality}, initial {variable.initial}) takes no "
                          "start value")
        return
    number_value = number(value, key, f"the start value of {component.name}.{name}", problems)
    if number_value is not None:
        component.start[name] = number_value


# Links and bonds -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Link:
    """The variables of one connection, directed from the outputs of ``source`` to the inputs of ``target``."""

    key: str  # the element that declares it
    source: Component
    outputs: tuple[str, ...]
    target: Component
    inputs: tuple[str, ...]
    quantity: str | None  # force, velocity, displacement, another quantity, or None: not declared
    bond: str | None = None  # the bond it belongs to by declaration (OSP: a port connection, powerBond)
    factor: float = 1.0  # the input receives factor * value + offset (SSP LinearTransformation)
    offset: float = 0.0

    def text(self) -> str:
        return (f"{self.source.name}.{'/'.join(self.outputs)} -> {self.target.name}.{'/'.join(self.inputs)}"
                f" ({self.quantity or 'no unit'})")


def orient(key: str, a: Component, a_names: list[str], b: Component, b_names: list[str],
           problems: Problems) -> tuple[Component, tuple[str, ...], Component, tuple[str, ...]] | None:
    """Variables ``a_names`` of ``a`` connected pairwise to ``b_names`` of ``b``, as (source, outputs,
    target, inputs) by their causality in the FMUs; None with a problem if not one way output → input."""
    if len(a_names) != len(b_names) or not a_names:
        problems.add(key, f"connects {len(a_names)} variable(s) of {a.name} to {len(b_names)} of {b.name}; "
                          "expected as many on both sides, at least one")
        return None
    found = [(check_variable(a, x, key, problems), check_variable(b, y, key, problems))
             for x, y in zip(a_names, b_names)]
    if any(va is None or vb is None for va, vb in found):
        return None
    directions = set()
    for (x, y), (va, vb) in zip(zip(a_names, b_names), found):
        pair = (va.causality, vb.causality)
        if pair == ("output", "input"):
            directions.add(1)
        elif pair == ("input", "output"):
            directions.add(-1)
        else:
            problems.add(key, f"connects {a.name}.{x} ({va.causality}) and {b.name}.{y} ({vb.causality}); "
                              "expected an output and an input")
            return None
    if len(directions) != 1:
        problems.add(key, f"connects variables of {a.name} and {b.name} in both directions; expected one group "
                          "to flow one way")
        return None
    if directions == {1}:
        return a, tuple(a_names), b, tuple(b_names)
    return b, tuple(b_names), a, tuple(a_names)


def link_quantity(key: str, source: Component, outputs: tuple[str, ...], target: Component,
                  inputs: tuple[str, ...], problems: Problems, declared: dict[tuple[str, str], str] | None = None,
                  definitions: dict[str, dict[str, UnitDefinition]] | None = None) -> str | None:
    """The quantity a link carries, from the units of its variables (``declared``: units a system description
    states for (subsystem, variable), resolved in ``definitions[subsystem]`` before the FMU's own): every
    variable of the link must have the same one. None when no variable declares a unit."""
    seen = set()
    for component, names in ((source, outputs), (target, inputs)):
        for name in names:
            found = _quantity(component, name, key, problems, declared, definitions)
            if found is not None:
                seen.add(found)
    if seen == {"torque", "energy"}:  # one end names its N.m a torque
        seen = {"torque"}
    if len(seen) > 1:
        problems.add(key, f"connects variables of different quantities: {', '.join(sorted(seen))}")
        return MIXED
    return seen.pop() if len(seen) == 1 else None


def _quantity(component: Component, name: str, key: str, problems: Problems,
              declared: dict[tuple[str, str], str] | None,
              definitions: dict[str, dict[str, UnitDefinition]] | None) -> str | None:
    variable = component.fmu.variables.get(name)
    if name in component.units:
        return stated_quantity(component, name, key, problems)
    candidates = []
    unit = (declared or {}).get((component.name, name))
    own = variable_unit(variable) if variable is not None else None
    if unit:
        units = {**component.fmu.units, **(definitions or {}).get(component.name, {})}
        same = own is not None and units.get(unit) == component.fmu.units.get(own)  # the FMU's own conversion
        candidates.append((unit, units, same))
    if own:
        candidates.append((own, component.fmu.units, True))
    found = set()
    for unit_name, units, convertible in candidates:
        exponents, problem = unit_exponents(unit_name, units, convertible)
        if problem:
            problems.add(key, f"{component.name}.{name}: {problem}")
        else:
            found.add(quantity_of(exponents, is_torque(unit_name, variable)))
    if found == {"torque", "energy"}:  # the same unit, named a torque in one of the two
        found = {"torque"}
    if len(found) > 1:
        problems.add(key, f"{component.name}.{name}: the system description and the FMU give it different "
                          f"quantities ({', '.join(sorted(found))})")
    return found.pop() if len(found) == 1 else None


def stated_quantity(component: Component, name: str, key: str, problems: Problems) -> str | None:
    """The quantity of a variable whose unit the scene states: an SI unit, which stands for the FMU's own where
    that is of the same quantity, is missing or unreadable, or is dimensionless (or lacks only the radian:
    ``subsystems.units.replaceable``), as the scene's ``units`` do when the FMU is loaded
    (``subsystems.models.external.model.apply_units``); else None with a problem."""
    stated, variable = component.units[name], component.fmu.variables.get(name)
    where_stated = f"subsystems.{component.name}.units.{name}"
    try:
        found = exponents(stated) if isinstance(stated, str) else None
    except UnitError as error:
        problems.add(where_stated, f"{error}; give an SI unit")
        return None
    if found is None:
        problems.add(where_stated, f"expected an SI unit as a string (e.g. \"N\", \"m/s\"), got {stated!r}")
        return None
    own = variable_unit(variable) if variable is not None else None
    own_exponents = unit_exponents(own, component.fmu.units)[0] if own else None
    if own_exponents is not None and own_exponents != found and not replaceable(own_exponents, found):
        problems.add(where_stated, unit_contradiction(name, f"FMU {component.fmu.label}", own, own_exponents, stated,
                                                      found))
        return None
    return quantity_of(found, is_torque(stated, variable) or (own_exponents == found and is_torque(own, variable)))


@dataclass
class Bond:
    """A power bond across two subsystems: the force (the effort of its domain: torque, pressure, voltage)
    one way, the velocity (the flow: angular velocity, volume flow, current) and the displacement (angle,
    volume, charge; none: ``displacement = []``) back."""

    key: str  # the element(s) that declare it
    force: Link  # force side -> motion side: the effort
    velocity: Link  # motion side -> force side: the flow
    displacement: list[Link] = field(default_factory=list)  # motion side -> force side, its components in order
    name: str | None = None  # as declared (OSP powerBond); None: numbered
    points: tuple[str | None, str | None] = (None, None)  # declared point names (OSP port groups): force, motion
    domain: str = "translational"  # a key of BOND_DOMAINS
    why_no_displacement: str | None = None  # for the note when ``displacement`` is empty

    @property
    def force_side(self) -> Component:
        return self.force.source

    @property
    def motion_side(self) -> Component:
        return self.force.target


def check_bond(bond: Bond, problems: Problems) -> bool:
    """The bond's velocity and displacement flow from its motion side to its force side, with as many
    components as its force (no displacement at all is a bond too: the force side receives the flow alone)."""
    force_side, motion_side = bond.force_side.name, bond.motion_side.name
    if force_side == motion_side:
        problems.add(bond.key, f"a bond of {force_side} with itself: a coupling joins two subsystems")
        return False
    ok = True
    effort, flow, displacement = BOND_DOMAINS[bond.domain]
    for role, links in ((flow, [bond.velocity]), (displacement, bond.displacement)):
        for link in links:
            if (link.source.name, link.target.name) != (motion_side, force_side):
                problems.add(link.key, f"the {role} of the bond whose {effort} {force_side} outputs must flow from "
                                       f"{motion_side} to {force_side}; got {link.text()}")
                ok = False
    sizes = {effort: len(bond.force.outputs), flow: len(bond.velocity.outputs)}
    if bond.displacement:  # none: the force side receives the flow alone (displacement = [])
        sizes[displacement] = sum(len(link.outputs) for link in bond.displacement)
    if len(set(sizes.values())) != 1:
        names = " and ".join(sizes) if len(sizes) == 2 else f"{effort}, {flow} and {displacement}"
        problems.add(bond.key, f"the bond {force_side} -> {motion_side} needs as many components of {names}, "
                               f"got {sizes}")
        ok = False
    return ok


def check_transformation(link: Link, problems: Problems) -> bool:
    """A transformation (``factor``, ``offset``) of a connection whose ends are converted at their FMU's
    boundary is applied to SI values; refused where the order would matter (an offset in the
    transformation or in an end's unit, with a scale on the other), as SSP leaves to the tool."""
    if link.factor == 1.0 and link.offset == 0.0:
        return True
    ends = [unit_definition(c, n) for c, names in ((link.source, link.outputs), (link.target, link.inputs))
            for n in names]
    scaled = [d for d in ends if converted(d)]
    if scaled and (link.offset != 0.0 or any(d.offset != 0.0 for d in scaled)):
        problems.add(link.key, f"{link.text()}: a transformation (factor {link.factor:g}, offset {link.offset:g}) "
                               "between variables whose units are not SI, one of them with an offset: zencosim "
                               "applies transformations to SI values, which here would not give what the file means; "
                               "give the connectors SI units, or fold the offset into the transformation")
        return False
    return True


def energy_output(component: Component, notes: list[str], coupled: frozenset[str] = frozenset()) -> str | None:
    """The FMU's output in joules (not a torque, nor a bond's effort: ``coupled``), when it has exactly one:
    its energy for zencosim's balance."""
    found = []
    for name, variable in component.fmu.variables.items():
        unit = variable_unit(variable)
        if variable.causality != "output" or variable.type not in REAL_TYPES or not unit or name in coupled:
            continue
        exponents, problem = unit_exponents(unit, component.fmu.units)
        if problem is None and exponents == QUANTITIES["energy"][1] and not is_torque(unit, variable):
            found.append(name)
    if len(found) == 1:
        notes.append(f"subsystems.{component.name}.energy = {found[0]!r}: the FMU's only output in J")
        return found[0]
    if found:
        notes.append(f"subsystems.{component.name}: no energy; the FMU has several outputs in J ({', '.join(found)}): "
                     "set energy to the one that is its stored energy")
    else:
        notes.append(f"subsystems.{component.name}: no energy (the FMU has no output in J); residual power is "
                     "still monitored at its bonds")
    return None


# Names, timing and the document -------------------------------------------------------------------

def scene_name(raw: str, used: set[str], what: str, notes: list[str]) -> str:
    """``raw`` as a scene name (letters, digits, ``_`` and ``-``), unique among ``used``."""
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", raw).strip("_") or "x"
    candidate, counter = name, 2
    while candidate in used:
        candidate, counter = f"{name}_{counter}", counter + 1
    used.add(candidate)
    if candidate != raw:
        notes.append(f"{what} {raw!r} is {candidate!r} in the scene (names are letters, digits, '_' and '-', unique)")
    return candidate


def document_path(fmu: Path, scene_directory: Path) -> str:
    """The FMU's path relative to the scene's directory, with '/' separators."""
    return Path(os.path.relpath(os.path.abspath(fmu), os.path.abspath(scene_directory))).as_posix()


def step_ns(seconds: float, key: str, what: str, problems: Problems) -> int | None:
    """A step size [s] as whole nanoseconds (``manager.scene.times``), or None with a problem naming ``what``."""
    try:
        return nanoseconds(seconds)
    except NotATime as error:
        problems.add(key, f"{what} {seconds!r} s: {error.expected}")
        return None


def set_timing(base_step: float, base_key: str, components: list[Component], problems: Problems) -> None:
    """Each component's communication ratio: its step over the base step, which must be whole."""
    base_ns = step_ns(base_step, base_key, "base step", problems)
    if base_ns is None:
        return
    for component in components:
        component_ns = step_ns(component.step, component.key, "step size", problems)
        if component_ns is None:
            continue
        if component_ns % base_ns:
            problems.add(component.key, f"step size {component.step!r} s is not a whole multiple of the base step "
                                        f"{base_step!r} s: zencosim communicates every whole number of base steps")
        else:
            component.comm_ratio = component_ns // base_ns


def settle_duration(requested: float | None, declared: float | None, declared_by: str, base_step: float,
                    components: list[Component], problems: Problems, notes: list[str]) -> float | None:
    """The run's duration: ``requested``, else ``declared`` (the file's, by ``declared_by``: where it comes
    from, or why there is none), else 10 s; rounded up to a whole number of periods (the base step times
    the lcm of the communication ratios)."""
    if requested is not None:
        value, origin = requested, "from the duration asked for"
        if isinstance(requested, bool) or not isinstance(requested, (int, float)) or not math.isfinite(requested) \
                or requested <= 0:
            problems.add("duration", f"expected a positive number of seconds, got {requested!r}")
            return None
    elif declared is not None:
        value, origin = declared, f"from {declared_by}"
    else:
        value, origin = DEFAULT_DURATION, f"assumed ({declared_by}, and no duration was asked for)"
    try:
        value_ns = nanoseconds(value, whole=False)
    except NotATime as error:  # NaN, beyond 64-bit nanoseconds, under 1 ns
        problems.add("duration", f"{value!r} s {origin}: {error.expected}")
        return None
    base_ns = nanoseconds(base_step)  # set_timing refused it unless it is a time
    period = base_ns * math.lcm(*[c.comm_ratio for c in components] or [1])
    periods = max(1, math.ceil(value_ns / period - 1e-9))
    duration = periods * period / 1e9
    rounded = (f" ({value!r} s rounded up to a whole number of periods of {period / 1e9!r} s)"
               if duration != value else "")
    notes.append(f"manager.duration = {duration!r} s: {origin}{rounded}")
    return duration


def signal_names(coupling: str, stem: str, size: int) -> str | list[str]:
    if size == 1:
        return f"{coupling}.{stem}"
    axes = "xyz" if size <= 3 else [str(i + 1) for i in range(size)]
    return [f"{coupling}.{stem}_{axes[i]}" for i in range(size)]


def _names_of(names: tuple[str, ...]) -> str | list[str]:
    return names[0] if len(names) == 1 else list(names)


def _units_not_declared(link: Link, units: dict[str, dict[str, str]]) -> None:
    """The SI unit of the link's quantity for each of its variables whose FMU declares no unit (the quantity
    comes from the system description's units or from the variable's partner, which a connection copies
    unchanged), into ``units[subsystem][variable]``."""
    if link.quantity is None or link.quantity == MIXED:
        return
    unit = _si_unit(link.quantity)
    for component, names in ((link.source, link.outputs), (link.target, link.inputs)):
        for name in names:
            variable = component.fmu.variables.get(name)
            if variable is not None and not variable_unit(variable):
                units[component.name][name] = unit


def _si_unit(quantity: str) -> str:
    """The SI unit of a link's quantity (:func:`quantity_of`'s names)."""
    if quantity in QUANTITIES:
        return QUANTITIES[quantity][0]
    return "1" if quantity == "dimensionless" else quantity  # the exponents written out, which units read


def build_document(name: str, description: str, base_step: float, duration: float, components: list[Component],
                   bonds: list[Bond], notes: list[str], signals_in: list[Link] = ()) -> dict:
    """The scene document of FMU subsystems, force–displacement couplings (``bonds``) and signal couplings
    (``signals_in``: one per pair of variables of each link, named ``<source>_<output>``); a component
    coupled to nothing runs free and publishes every output (``outputs = "all"``)."""
    used_couplings: set[str] = set()
    coupling_names = {}
    for bond in bonds:  # declared names first, so that numbered ones do not take them
        if bond.name is not None:
            coupling_names[id(bond)] = scene_name(bond.name, used_couplings, "the bond", notes)
    counter = 0
    for bond in bonds:
        if bond.name is None:
            counter += 1
            while f"c{counter}" in used_couplings:
                counter += 1
            coupling_names[id(bond)] = f"c{counter}"
            used_couplings.add(f"c{counter}")
    points: dict[str, dict[str, dict]] = {c.name: {} for c in components}
    used_points: dict[str, set[str]] = {c.name: set() for c in components}
    declared_points = {}
    for bond in bonds:
        for side, declared in zip((bond.force_side, bond.motion_side), bond.points):
            if declared is not None:
                declared_points[(id(bond), side.name)] = scene_name(declared, used_points[side.name],
                                                                    f"the port of {side.name}", notes)
    point_counter = 0
    couplings, signals = {}, []
    signal_links = list(signals_in)
    fed = {side.name for bond in bonds for side in (bond.force_side, bond.motion_side)}
    units: dict[str, dict[str, str]] = {c.name: {} for c in components}
    efforts: dict[str, set[str]] = {c.name: set() for c in components}
    for bond in bonds:
        coupling = coupling_names[id(bond)]
        efforts[bond.force_side.name].update(bond.force.outputs)
        for link in (bond.force, bond.velocity, *bond.displacement):
            _units_not_declared(link, units)
        side_points = []
        for side in (bond.force_side, bond.motion_side):
            point = declared_points.get((id(bond), side.name))
            if point is None:
                point_counter += 1
                while f"p{point_counter}" in used_points[side.name]:
                    point_counter += 1
                point = f"p{point_counter}"
                used_points[side.name].add(point)
            side_points.append(point)
        displacement = tuple(n for link in bond.displacement for n in link.outputs)
        position_input = tuple(n for link in bond.displacement for n in link.inputs)
        domain = {"domain": bond.domain} if bond.domain != "translational" else {}
        force_point = {**domain, "force": _names_of(bond.force.outputs)}
        motion_point = {**domain, "force_input": _names_of(bond.force.inputs)}
        if displacement:
            force_point["position_input"] = _names_of(position_input)
            motion_point["position"] = _names_of(displacement)
        force_point["velocity_input"] = _names_of(bond.velocity.inputs)
        motion_point["velocity"] = _names_of(bond.velocity.outputs)
        points[bond.force_side.name][side_points[0]] = force_point
        points[bond.motion_side.name][side_points[1]] = motion_point
        size = len(bond.force.outputs)
        couplings[coupling] = {
            "type": "force_displacement", **domain,
            "force_side": f"{bond.force_side.name}.{side_points[0]}",
            "motion_side": f"{bond.motion_side.name}.{side_points[1]}",
            "force": signal_names(coupling, "f", size),
            "displacement": signal_names(coupling, "x", size) if displacement else [],
            "velocity": signal_names(coupling, "v", size)}
        effort, flow, displacement_quantity = BOND_DOMAINS[bond.domain]
        if bond.domain != "translational":
            notes.append(f"couplings.{coupling}.domain = {bond.domain!r}: a {bond.domain} bond ({bond.key}); its force "
                         f"signal is the {effort}, its velocity the {flow}, its displacement the "
                         f"{displacement_quantity}")
        if not displacement:
            notes.append(f"couplings.{coupling}.displacement = []: {bond.why_no_displacement or 'no displacement'}; "
                         f"{bond.force_side.name} receives the {flow} alone (an input of it that no connection "
                         "feeds keeps its start value, as in libcosim)")
        if bond.force.factor != 1.0:
            couplings[coupling]["force_factor"] = bond.force.factor
            notes.append(f"couplings.{coupling}.force_factor = {bond.force.factor!r}: the transformation of its force "
                         f"connection ({bond.force.key}); the bond's force signal is {bond.force.factor!r} times "
                         f"{bond.force_side.name}'s force output")
        for stem in ("x", "f") if displacement else ("v", "f"):  # no displacement: the flow and the effort
            names = signal_names(coupling, stem, size)
            signals += [names] if isinstance(names, str) else names
    for link in signal_links:
        _units_not_declared(link, units)
        for output, input_ in zip(link.outputs, link.inputs):
            coupling = scene_name(f"{link.source.name}_{output}", used_couplings, f"the signal of {link.key}", [])
            table = {"type": "signal", "output": f"{link.source.name}.{output}",
                     "input": f"{link.target.name}.{input_}"}
            if link.factor != 1.0:
                table["factor"] = link.factor
            if link.offset != 0.0:
                table["offset"] = link.offset
            couplings[coupling] = table
            signals.append(coupling)
            transformed = "" if link.factor == 1.0 and link.offset == 0.0 else \
                f", the input receiving {link.factor:g} * value + {link.offset:g}"
            notes.append(f"couplings.{coupling}: a signal coupling, {link.source.name}.{output} -> "
                         f"{link.target.name}.{input_} ({link.key}){transformed}")
            fed.update({link.source.name, link.target.name})
    subsystems = {}
    for component in components:
        table: dict[str, Any] = {"model": "fmu", "fmu": component.path, "micro_step": component.step}
        if component.comm_ratio != 1:
            table["comm_ratio"] = component.comm_ratio
        if component.start:
            table["start"] = dict(component.start)
        energy = energy_output(component, notes, frozenset(efforts[component.name]))
        if energy is not None:
            table["energy"] = energy
        if units[component.name]:
            table["units"] = units[component.name]
            notes.append(f"subsystems.{component.name}.units = {units[component.name]!r}: the FMU declares no unit "
                         "for these variables; the system description's connections give their quantities")
        if points[component.name]:
            table["points"] = points[component.name]
        if component.name not in fed:
            table["outputs"] = "all"
            notes.append(f"subsystems.{component.name}.outputs = 'all': {component.key} is coupled to nothing; it runs "
                         "free and publishes every output variable as a signal of its name")
        subsystems[component.name] = table
    notes.append("outputs.reference = 'none': FMU subsystems have no reference solution; outputs.signals: each "
                 "coupling's displacement (without one, its velocity) and force, and each signal coupling's signal")
    return {"name": name, "description": description,
            "manager": {"duration": duration, "macro_step": base_step},
            "outputs": {"signals": signals, "reference": "none"},
            "subsystems": subsystems, "couplings": couplings}
