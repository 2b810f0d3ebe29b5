"""Scenes: load a TOML scene, apply ``--set`` overrides, validate everything, and report every problem.

A scene says what is simulated and nothing more: subsystems (model, integrator, micro-step,
communication-step ratio, the model's bodies and effects), couplings (which subsystem computes the
coupling force and which signals cross), the manager (scheme, macro-step, extrapolation, timeout,
pacing) and outputs (signals to report, the reference to compare with). See docs/scenes.md.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

from zencosim.manager.scene.checks import (
    check_compensation,
    check_couplings,
    check_names,
    check_scheme,
    check_step_control,
    check_timing,
)
from zencosim.manager.scene.couplings import COUPLINGS
from zencosim.manager.scene.overrides import apply_overrides, parse_override
from zencosim.manager.scene.settings import (
    CorrectionSettings,
    EnergyControlSettings,
    ImplicitSettings,
    ManagerSettings,
    OutputSettings,
    SpikeSettings,
    SubsystemScene,
    SubsystemSettings,
)
from zencosim.subsystems.models import MODELS, model_class, model_traits
from zencosim.subsystems.models.external.python_model import ModelClassError
from zencosim.subsystems.params import Problems, read_table

SECTIONS = ("name", "description", "source", "manager", "outputs", "subsystems", "couplings")
DEEPEST = 12  # tables and arrays nested deeper than this are refused (the bundled scenes go 5 deep)


class SceneError(ValueError):
    """A scene that cannot be run: every problem, each with the file and dotted key it concerns."""

    def __init__(self, path: str, problems: Sequence) -> None:
        self.path = path
        self.problems = list(problems)
        lines = [f"{path}: {p.key}: {p.reason}" for p in self.problems]
        super().__init__(f"scene {path} has {len(lines)} problem(s):\n  " + "\n  ".join(lines))


@dataclass(frozen=True)
class Scene:
    """A validated, immutable description of a run."""

    name: str
    description: str
    path: str  # where it was loaded from
    overrides: tuple[str, ...]  # the ``--set`` arguments applied, in order
    resolved: dict  # the TOML document after overrides (do not mutate)
    manager: ManagerSettings
    outputs: OutputSettings
    subsystems: dict[str, SubsystemScene]
    couplings: dict[str, Any]
    notes: tuple[str, ...] = ()  # what an imported system description's mapping assumed (manager.scene.imports)

    @property
    def digest(self) -> str:
        """sha256 of the resolved scene: two processes that loaded the same run agree on it."""
        return hashlib.sha256(json.dumps(self.resolved, sort_keys=True).encode()).hexdigest()

    def comm_step_ns(self, subsystem: str) -> int:
        return self.manager.macro_step_ns * self.subsystems[subsystem].settings.comm_ratio

    @property
    def replaced_units(self) -> dict[str, dict[str, str]]:
        """``<subsystem>.<variable>`` -> ``{"declared": …, "scene": …}``: the dimensionless units of FMUs and
        Python models that the scene's ``units`` replaced (``subsystems.models.external.model.apply_units``)."""
        return {f"{name}.{variable}": {"declared": declared, "scene": unit}
                for name, subsystem in self.subsystems.items()
                for variable, (declared, unit) in getattr(subsystem.spec, "replaced_units", {}).items()}


def bundled_scene_names() -> list[str]:
    """Names of the scenes that ship with zencosim."""
    return sorted(p.name[:-5] for p in resources.files("zencosim.scenes").iterdir() if p.name.endswith(".toml"))


# OSP system structures, SSP systems and one FMU run alone (manager.scene.imports)
SYSTEM_DESCRIPTIONS = (".xml", ".ssp", ".ssd", ".fmu")


def scene_path(name_or_path: str) -> Path:
    """A bundled scene name, or a path to a TOML scene or a system description (OSP XML, SSP, an FMU)."""
    candidate = Path(name_or_path)
    if candidate.suffix in (".toml", *SYSTEM_DESCRIPTIONS) or candidate.exists():
        return candidate
    bundled = resources.files("zencosim.scenes") / f"{name_or_path}.toml"
    if bundled.is_file():
        return Path(str(bundled))
    raise SceneError(name_or_path, [_problem("scene", "no such file and no bundled scene of that name; "
                                             f"bundled: {', '.join(bundled_scene_names())}")])


def _problem(key: str, reason: str):
    problems = Problems()
    problems.add(key, reason)
    return problems[0]


def load_scene(name_or_path: str, overrides: Sequence[str] = ()) -> Scene:
    """Load, override and validate a scene (a TOML scene, or an OSP or SSP system description mapped onto
    one); raise :class:`SceneError` listing every problem."""
    path = scene_path(name_or_path)
    if path.suffix in SYSTEM_DESCRIPTIONS:
        from zencosim.manager.scene.imports import import_system
        options, applied = _import_options(overrides)
        document, notes = import_system(path, **options)
        if path.suffix == ".fmu":  # start.<variable> is the one subsystem's
            (name,) = document["subsystems"]
            applied = [f"subsystems.{name}.{o}" if o.startswith("start.") else o for o in applied]
        return scene_from_document(document, str(path), applied, tuple(notes), given=overrides)
    refuse_irregular(path, "scene")
    try:
        text = path.read_text()
    except OSError as error:
        raise SceneError(str(path), [_problem("scene", f"cannot read: {error.strerror}")]) from None
    return scene_from_text(text, str(path), overrides)


def refuse_irregular(path: Path, key: str) -> None:
    """Raise a :class:`SceneError` at ``key`` when ``path`` is there but no regular file: reading a device
    (``/dev/zero``) or a pipe would not end, a folder cannot be read."""
    if path.exists() and not path.is_file():
        raise SceneError(str(path), [_problem(key, "not a regular file; expected a TOML scene, an OSP system "
                                                   "structure (.xml), an SSP system (.ssp, .ssd) or an FMU")])


IMPORT_OPTIONS = {"manager.algorithm": "algorithm", "input": "input_table"}  # override key -> import_system's


def _import_options(overrides: Sequence[str]) -> tuple[dict, list[str]]:
    """What overrides ask of how a system description is mapped (they are taken before the others):
    ``manager.algorithm=fixed`` (an OSP ``ecco`` system at its base step), ``input=table.csv`` (a lone FMU's
    input values), ``subsystems.<name>.units.<variable>=UNIT`` (the quantities of connections, which the import
    reads from units; applied to the scene too); and the other overrides."""
    options: dict = {}
    others = []
    for override in overrides:
        try:
            path, value = parse_override(override)
        except ValueError:  # apply_overrides says what is wrong with it
            path, value = [], None
        key = ".".join(path)
        if key in IMPORT_OPTIONS:
            options[IMPORT_OPTIONS[key]] = str(value)
            continue
        if len(path) == 4 and path[0] == "subsystems" and path[2] == "units":
            options.setdefault("units", {}).setdefault(path[1], {})[path[3]] = value
        others.append(override)
    return options, others


def scene_from_text(text: str, path: str, overrides: Sequence[str] = ()) -> Scene:
    """Parse, override and validate a scene's TOML ``text``; ``path`` names it in errors and in ``Scene.path``."""
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SceneError(path, [_problem("scene", f"not valid TOML: {error}")]) from None
    except ValueError:  # Python reads no integer of more than sys.get_int_max_str_digits() digits
        raise SceneError(path, [_problem("scene", f"an integer of more than {sys.get_int_max_str_digits()} digits; "
                                                  "expected a number a float holds")]) from None
    except RecursionError:  # tomllib parses nested arrays and tables recursively
        raise SceneError(path, [_problem("scene", f"arrays or tables nested too deeply; expected at most "
                                         f"{DEEPEST} levels")]) from None
    return scene_from_document(document, path, overrides)


def scene_from_document(document: dict, path: str, overrides: Sequence[str] = (), notes: tuple[str, ...] = (),
                        given: Sequence[str] | None = None) -> Scene:
    """Override and validate a scene document; paths in it are relative to ``path``'s directory. ``given``: the
    overrides as the user gave them, which load the scene again from ``path`` (``Scene.overrides``; default
    ``overrides``)."""
    problems = Problems()
    _refuse_deep(document, path)
    resolved = apply_overrides(document, overrides, problems)
    _refuse_deep(resolved, path)
    scene = _validate(resolved, path, tuple(overrides if given is None else given), problems)
    if problems:
        raise SceneError(path, problems)
    return dataclasses.replace(scene, notes=notes)


def _refuse_deep(document: dict, path: str) -> None:
    """Raise a :class:`SceneError` naming the first value nested deeper than ``DEEPEST`` (found without
    recursion: the checks after it copy and serialise the document recursively)."""
    pending = [((), document)]
    while pending:
        keys, node = pending.pop()
        if len(keys) > DEEPEST:
            raise SceneError(path, [_problem(".".join(map(str, keys[:DEEPEST + 1])), f"nested too deeply; expected "
                                             f"at most {DEEPEST} levels of arrays and tables")])
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        pending += [(keys + (key,), value) for key, value in items]


def _validate(doc: dict, path: str, overrides: tuple[str, ...], problems: Problems) -> Scene | None:
    for extra in sorted(set(doc) - set(SECTIONS)):
        problems.add(extra, f"unknown key; expected one of: {', '.join(SECTIONS)}")
    name = doc.get("name")
    if not isinstance(name, str) or not name:
        problems.add("name", "missing; expected the scene's name as a string")
    for key in ("description", "source"):
        if not isinstance(doc.get(key, ""), str):
            problems.add(key, f"expected a string, got {type(doc[key]).__name__}")
    description = doc.get("description", "")
    manager = _read_manager(doc.get("manager"), problems)
    outputs = read_table(OutputSettings, doc.get("outputs", {}), "outputs", problems)
    tables = doc.get("subsystems")
    if not isinstance(tables, dict) or not tables:
        problems.add("subsystems", "expected at least one [subsystems.<name>] table")
        tables = {}
    subsystems = _read_subsystems(tables, Path(path).parent, problems)
    coupling_tables = doc.get("couplings", {})
    couplings = _read_couplings(coupling_tables, problems)
    check_names(tables, coupling_tables if isinstance(coupling_tables, dict) else {}, couplings, problems)

    if manager is not None:
        check_timing(manager, tables, subsystems, problems)
        if manager.compensation != "none":
            check_compensation(manager, couplings, subsystems, problems)
        check_scheme(manager, outputs, couplings, subsystems, problems)
        check_step_control(manager, couplings, subsystems, problems)
    check_couplings(couplings, subsystems, tables, problems)
    if outputs is not None:
        signals = {s for c in couplings.values() for s in c.signals()}
        for i, signal in enumerate(outputs.signals):
            if signal not in signals:
                problems.add(f"outputs.signals[{i}]", f"unknown signal {signal!r}; expected one of "
                             f"{', '.join(sorted(signals)) or '(no coupling signals)'}")
    if problems:
        return None
    return Scene(name, description, path, overrides, doc, manager, outputs, subsystems, couplings)


GENERIC_SUBSYSTEM_KEYS = tuple(f.name for f in dataclasses.fields(SubsystemSettings))  # the rest is the model's


def _read_subsystems(tables: dict, directory: Path, problems: Problems) -> dict[str, SubsystemScene]:
    """Each ``[subsystems.<name>]`` table: its generic settings, and the rest as its model reads it (paths
    relative to ``directory``); the integrator, when the table names none, is the model's default."""
    subsystems = {}
    for sub_name, table in tables.items():
        key = f"subsystems.{sub_name}"
        if not isinstance(table, dict):
            problems.add(key, "expected a table")
            continue
        generic = {k: v for k, v in table.items() if k in GENERIC_SUBSYSTEM_KEYS}
        settings = read_table(SubsystemSettings, generic, key, problems)
        if settings is None:
            continue
        try:
            model = model_class(settings.model)
        except ModelClassError as error:
            problems.add(f"{key}.model", f"{error}; built-in models: {', '.join(sorted(MODELS))}, or \"fmu\"")
            continue
        spec = model.read({k: v for k, v in table.items() if k not in GENERIC_SUBSYSTEM_KEYS}, key, problems, directory)
        if spec is None:
            continue
        traits = model_traits(model, spec)
        if settings.integrator is None:
            settings = dataclasses.replace(settings, integrator=traits.default_integrator)
        reason = settings.integrator_problem(traits)
        if reason is None and settings.integrator == "exact" and spec.linear_problem():
            reason = f"'exact' needs a linear, time-invariant model: {spec.linear_problem()}"
        if reason is not None:
            problems.add(f"{key}.integrator", reason)
            continue
        subsystems[sub_name] = SubsystemScene(sub_name, settings, spec)
    return subsystems


def _read_couplings(tables: Any, problems: Problems) -> dict[str, Any]:
    """Each ``[couplings.<name>]`` table, read by the coupling class its ``type`` names."""
    if not isinstance(tables, dict):
        problems.add("couplings", "expected [couplings.<name>] tables")
        return {}
    couplings = {}
    for coupling_name, table in tables.items():
        key = f"couplings.{coupling_name}"
        kind = table.get("type") if isinstance(table, dict) else None
        if not isinstance(kind, str) or kind not in COUPLINGS:
            problems.add(f"{key}.type", f"expected one of {', '.join(sorted(COUPLINGS))}, got {kind!r}")
            continue
        coupling = COUPLINGS[kind].read(coupling_name, table, key, problems)
        if coupling is not None:
            couplings[coupling_name] = coupling
    return couplings


def _read_manager(table: Any, problems: Problems) -> ManagerSettings | None:
    """``[manager]`` with its ``correction``, ``spikes``, ``implicit`` and ``energy_control`` sub-tables
    (``implicit``: with scheme "implicit" only, defaults when absent; ``energy_control``: required with
    step_control "energy", not used without)."""
    parts = ("correction", "spikes", "implicit", "energy_control")
    manager = read_table(ManagerSettings, table, "manager", problems, skip=parts)
    if manager is None:
        return None
    settings = {}
    for part, cls in zip(parts[:2], (CorrectionSettings, SpikeSettings)):
        if part in table:
            settings[part] = read_table(cls, table[part], f"manager.{part}", problems)
    if manager.scheme == "implicit":
        settings["implicit"] = read_table(ImplicitSettings, table.get("implicit", {}), "manager.implicit", problems)
    elif "implicit" in table:
        problems.add("manager.implicit", f"only with manager.scheme = 'implicit', got {manager.scheme!r}")
    if manager.step_control == "energy" or "energy_control" in table:  # unused at a fixed step (a study varies it)
        settings["energy_control"] = read_table(EnergyControlSettings, table.get("energy_control", {}),
                                                "manager.energy_control", problems)
    return dataclasses.replace(manager, **{k: v for k, v in settings.items() if v is not None})
