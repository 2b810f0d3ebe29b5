"""Scenes: load a TOML scene, apply ``--set`` overrides, validate everything, and report every problem.

A scene says what is simulated and nothing more: subsystems (model, integrator, micro-step,
communication-step ratio, the model's bodies and effects), couplings (which subsystem computes the
coupling force and which signals cross), the manager (scheme, macro-step, extrapolation, timeout,
pacing) and outputs (signals to report, the reference to compare with). See docs/scenes.md.
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Literal, Sequence

from compensation.coupling_decompositions import DECOMPOSITIONS
from compensation.implicit_coupling_laws import Baumgarte, CouplingMethod, Projection, WeightedMultiplier, check_supported
from manager.couplings import COUPLINGS, RigidJoint
from subsystems.integrators import INTEGRATORS
from subsystems.models import MODELS
from subsystems.params import Problems, quantity, read_table

SECTIONS = ("name", "description", "source", "manager", "outputs", "subsystems", "couplings")


class SceneError(ValueError):
    """A scene that cannot be run: every problem, each with the file and dotted key it concerns."""

    def __init__(self, path: str, problems: Sequence) -> None:
        self.path = path
        self.problems = list(problems)
        lines = [f"{path}: {p.key}: {p.reason}" for p in self.problems]
        super().__init__(f"scene {path} has {len(lines)} problem(s):\n  " + "\n  ".join(lines))


@dataclass(frozen=True)
class CorrectionSettings:
    """The ``[manager.correction]`` table: energy correction (paper 002 Eqs. 13–17, see manager.correction).

    No table, or ``enabled = false``: no corrector is built.
    """

    enabled: bool = True
    mu: float | Literal["auto"] = field(default="auto", metadata=quantity("", minimum=0.0, maximum=1.0))  # μ, Eq. 13
    nu: float = field(default=0.0, metadata=quantity("", minimum=0.0, maximum=1.0))  # ν, weight of 𝒰 in Eq. 17
    cap_fraction: float | None = field(default=1.0, metadata=quantity("", minimum=0.0))  # |f_corr| <= cap_fraction |f|
    cap_force: float | None = field(default=None, metadata=quantity("N", minimum=0.0))  # |f_corr| <= cap_force [N]


@dataclass(frozen=True)
class SpikeSettings:
    """The ``[manager.spikes]`` table: the residual-power spike detector (see manager.monitor)."""

    window: float = field(default=2.0, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # trailing window [s]
    threshold: float = field(default=50.0, metadata=quantity("", minimum=0.0, exclusive_minimum=True))  # x baseline
    merge_gap: float = field(default=0.1, metadata=quantity("s", minimum=0.0))  # flagged points closer than this join [s]


@dataclass(frozen=True)
class ImplicitSettings:
    """The ``[manager.implicit]`` table: the coupling method of paper 003 and its corrector iteration.

    The degree k of the predictor and corrector polynomials is ``manager.extrapolation``. Parameters of
    the methods not chosen are not used.
    """

    method: Literal["baumgarte", "weighted-multiplier", "projection"] = "baumgarte"
    mu: float = field(default=5e-3, metadata=quantity("s", minimum=0.0))  # Baumgarte: beta = 2 mu [s], gamma = mu^2 [s^2] (§3.7.1)
    index: int = field(default=1, metadata=quantity("", minimum=1, maximum=3))  # Baumgarte: 1, 2 (gamma = 0), 3 (beta = gamma = 0)
    a: float = field(default=1.0, metadata=quantity("", minimum=0.0))  # weighted multiplier: weight of the velocity level
    b: float = field(default=1.0, metadata=quantity("", minimum=0.0))  # weighted multiplier: weight of the acceleration level
    max_iterations: int = field(default=1, metadata=quantity("", minimum=1))  # corrector runs per macro-step
    tolerance: float = field(default=1e-8, metadata=quantity("", minimum=0.0))  # relative change of e ending the iteration
    sensitivity_step: float = field(default=1e-4, metadata=quantity("", minimum=0.0, exclusive_minimum=True))  # relative perturbation of e
    divergence_gap: float = field(default=1.0, metadata=quantity("m", minimum=0.0, exclusive_minimum=True))  # the run stops when the joint opens wider

    def coupling_method(self) -> CouplingMethod:
        """The method with its parameters in SI units (Baumgarte's beta [s] and gamma [s^2])."""
        if self.method == "baumgarte":
            return Baumgarte.from_mu(self.mu, self.index)
        if self.method == "weighted-multiplier":
            return WeightedMultiplier(self.a, self.b)
        return Projection()


@dataclass(frozen=True)
class ManagerSettings:
    """The ``[manager]`` table: how the run is orchestrated."""

    duration: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # simulated time [s]
    macro_step: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # base communication step [s]
    scheme: Literal["jacobi", "implicit"] = "jacobi"
    extrapolation: int = field(default=0, metadata=quantity("", minimum=0, maximum=2))  # Lagrange order (implicit: k)
    timeout: float = field(default=10.0, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))
    realtime: bool = False
    record: str = ""  # write an MCAP recording of every run to this path ("" = none; also: zencosim run --record)
    correction: CorrectionSettings | None = None  # [manager.correction]
    spikes: SpikeSettings = SpikeSettings()  # [manager.spikes]
    compensation: Literal["none", "eigenstructure"] = "none"  # paper 000 compensator (docs/compensation.md)
    implicit: ImplicitSettings | None = None  # [manager.implicit], with scheme = "implicit"

    @property
    def corrects(self) -> bool:
        """True when the scene asks for energy correction."""
        return self.correction is not None and self.correction.enabled

    @property
    def macro_step_ns(self) -> int:
        return round(self.macro_step * 1e9)

    @property
    def duration_ns(self) -> int:
        return round(self.duration * 1e9)


@dataclass(frozen=True)
class OutputSettings:
    """The ``[outputs]`` table: which signals the summary reports and against which reference."""

    signals: tuple[str, ...] = ()
    reference: Literal["analytic", "solve_ivp", "none"] = "analytic"


@dataclass(frozen=True)
class SubsystemSettings:
    """The generic keys of a ``[subsystems.<name>]`` table; the rest belongs to its model."""

    model: str
    micro_step: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # [s]
    integrator: str = "symplectic_euler"
    comm_ratio: int = field(default=1, metadata=quantity("", minimum=1))  # communication step / macro step
    extrapolation: int | None = field(default=None, metadata=quantity("", minimum=0, maximum=2))  # of its inputs

    def problems(self) -> list[tuple[str, str]]:
        found = []
        if self.model not in MODELS:
            found.append(("model", f"expected one of {', '.join(sorted(MODELS))}, got {self.model!r}"))
        if self.integrator not in INTEGRATORS:
            found.append(("integrator", f"expected one of {', '.join(sorted(INTEGRATORS))}, got {self.integrator!r}"))
        elif self.model in MODELS and INTEGRATORS[self.integrator].second_order_only and not MODELS[self.model].second_order:
            usable = sorted(n for n, i in INTEGRATORS.items() if not i.second_order_only)
            found.append(("integrator", f"{self.integrator} needs a state of positions and velocities; model "
                                        f"{self.model} is first order: expected one of {', '.join(usable)}"))
        return found

    @property
    def micro_step_ns(self) -> int:
        return round(self.micro_step * 1e9)


@dataclass(frozen=True)
class SubsystemScene:
    """One subsystem of a scene: its generic settings and its model's own description."""

    name: str
    settings: SubsystemSettings
    spec: Any  # what the model's ``read`` returned


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

    @property
    def digest(self) -> str:
        """sha256 of the resolved scene: two processes that loaded the same run agree on it."""
        return hashlib.sha256(json.dumps(self.resolved, sort_keys=True).encode()).hexdigest()

    def comm_step_ns(self, subsystem: str) -> int:
        return self.manager.macro_step_ns * self.subsystems[subsystem].settings.comm_ratio


def bundled_scene_names() -> list[str]:
    """Names of the scenes that ship with zencosim."""
    return sorted(p.name[:-5] for p in resources.files("scenes").iterdir() if p.name.endswith(".toml"))


def scene_path(name_or_path: str) -> Path:
    """A bundled scene name or a path to a TOML file."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        return candidate
    bundled = resources.files("scenes") / f"{name_or_path}.toml"
    if bundled.is_file():
        return Path(str(bundled))
    raise SceneError(name_or_path, [_problem("scene", "no such file and no bundled scene of that name; "
                                             f"bundled: {', '.join(bundled_scene_names())}")])


def _problem(key: str, reason: str):
    problems = Problems()
    problems.add(key, reason)
    return problems[0]


def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``a.b.c=value`` into a key path and a TOML value (a bare word is taken as a string)."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"--set {text!r}: expected key=value, e.g. manager.macro_step=0.004")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.strip().split("."), value


def apply_overrides(document: dict, overrides: Sequence[str], problems: Problems) -> dict:
    """Return a copy of ``document`` with each ``key=value`` set; tables cannot be overwritten by scalars."""
    result = copy.deepcopy(document)
    for text in overrides:
        try:
            path, value = parse_override(text)
        except ValueError as error:
            problems.add("--set", str(error))
            continue
        node = result
        for depth, part in enumerate(path[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                problems.add(".".join(path[:depth + 1]), f"--set {text}: is a value, not a table")
                break
            node = child
        else:
            if isinstance(node.get(path[-1]), dict) or isinstance(value, dict):
                problems.add(".".join(path), f"--set {text}: only scalars can be overridden")
            else:
                node[path[-1]] = value
    return result


def _whole_ns(seconds: float, key: str, problems: Problems) -> None:
    if abs(seconds * 1e9 - round(seconds * 1e9)) > 1e-3:
        problems.add(key, f"expected a whole number of nanoseconds, got {seconds!r} s")


def load_scene(name_or_path: str, overrides: Sequence[str] = ()) -> Scene:
    """Load, override and validate a scene; raise :class:`SceneError` listing every problem."""
    path = scene_path(name_or_path)
    try:
        text = path.read_text()
    except OSError as error:
        raise SceneError(str(path), [_problem("scene", f"cannot read: {error.strerror}")]) from None
    return scene_from_text(text, str(path), overrides)


def scene_from_text(text: str, path: str, overrides: Sequence[str] = ()) -> Scene:
    """Parse, override and validate a scene's TOML ``text``; ``path`` names it in errors and in ``Scene.path``."""
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SceneError(path, [_problem("scene", f"not valid TOML: {error}")]) from None
    problems = Problems()
    resolved = apply_overrides(document, overrides, problems)
    scene = _validate(resolved, path, tuple(overrides), problems)
    if problems:
        raise SceneError(path, problems)
    return scene


def _validate(doc: dict, path: str, overrides: tuple[str, ...], problems: Problems) -> Scene | None:
    for extra in sorted(set(doc) - set(SECTIONS)):
        problems.add(extra, f"unknown key; expected one of: {', '.join(SECTIONS)}")
    name = doc.get("name")
    if not isinstance(name, str) or not name:
        problems.add("name", "missing; expected the scene's name as a string")
    description = doc.get("description", "")
    manager = _read_manager(doc.get("manager"), problems)
    outputs = read_table(OutputSettings, doc.get("outputs", {}), "outputs", problems)

    subsystems: dict[str, SubsystemScene] = {}
    tables = doc.get("subsystems")
    if not isinstance(tables, dict) or not tables:
        problems.add("subsystems", "expected at least one [subsystems.<name>] table")
        tables = {}
    generic = ("model", "integrator", "micro_step", "comm_ratio", "extrapolation")
    for sub_name, table in tables.items():
        key = f"subsystems.{sub_name}"
        if not isinstance(table, dict):
            problems.add(key, "expected a table")
            continue
        settings = read_table(SubsystemSettings, {k: v for k, v in table.items() if k in generic}, key, problems)
        if settings is None:
            continue
        spec = MODELS[settings.model].read({k: v for k, v in table.items() if k not in generic}, key, problems)
        if spec is not None:
            subsystems[sub_name] = SubsystemScene(sub_name, settings, spec)
            if settings.integrator == "exact" and spec.linear_problem():
                problems.add(f"{key}.integrator", f"'exact' needs a linear, time-invariant model: {spec.linear_problem()}")

    couplings: dict[str, Any] = {}
    coupling_tables = doc.get("couplings", {})
    if not isinstance(coupling_tables, dict):
        problems.add("couplings", "expected [couplings.<name>] tables")
        coupling_tables = {}
    for coupling_name, table in coupling_tables.items():
        key = f"couplings.{coupling_name}"
        kind = table.get("type") if isinstance(table, dict) else None
        if kind not in COUPLINGS:
            problems.add(f"{key}.type", f"expected one of {', '.join(sorted(COUPLINGS))}, got {kind!r}")
            continue
        coupling = COUPLINGS[kind].read(coupling_name, table, key, problems)
        if coupling is not None:
            couplings[coupling_name] = coupling

    if manager is not None:
        _check_timing(manager, tables, subsystems, problems)
        if manager.compensation != "none":
            check_compensation(manager, couplings, subsystems, problems)
        _check_scheme(manager, outputs, couplings, subsystems, problems)
    _check_couplings(couplings, subsystems, tables, problems)
    if outputs is not None:
        signals = {s for c in couplings.values() for s in c.signals()}
        for i, signal in enumerate(outputs.signals):
            if signal not in signals:
                problems.add(f"outputs.signals[{i}]", f"unknown signal {signal!r}; expected one of "
                             f"{', '.join(sorted(signals)) or '(no coupling signals)'}")
    if problems:
        return None
    return Scene(name, description, path, overrides, doc, manager, outputs, subsystems, couplings)


def _read_manager(table: Any, problems: Problems) -> ManagerSettings | None:
    """``[manager]`` with its ``correction``, ``spikes`` and ``implicit`` sub-tables (``implicit``: with
    scheme "implicit" only, defaults when absent)."""
    parts = ("correction", "spikes", "implicit")
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
    return dataclasses.replace(manager, **{k: v for k, v in settings.items() if v is not None})


def _check_scheme(manager: ManagerSettings, outputs: OutputSettings | None, couplings: dict,
                  subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """Rigid joints need the implicit scheme, which handles one rigid joint, single-rate, with the scene's
    extrapolation order as k and no energy correction (paper 003 §2)."""
    joints = [c for c in couplings.values() if isinstance(c, RigidJoint)]
    if manager.scheme == "jacobi":
        for joint in joints:
            problems.add(f"couplings.{joint.name}.type", "a rigid joint needs manager.scheme = 'implicit': an "
                         "explicit scheme cannot hold an algebraic constraint")
    else:
        for coupling in couplings.values():
            if not isinstance(coupling, RigidJoint):
                problems.add(f"couplings.{coupling.name}.type", f"the implicit scheme couples through rigid joints "
                             f"only, got {coupling.kind!r}")
        if len(joints) != 1:
            problems.add("couplings", f"the implicit scheme handles exactly one rigid joint, got {len(joints)}")
        for sub in subsystems.values():
            if sub.settings.comm_ratio != 1:
                problems.add(f"subsystems.{sub.name}.comm_ratio", "expected 1: the implicit scheme is single-rate")
            if sub.settings.extrapolation is not None:
                problems.add(f"subsystems.{sub.name}.extrapolation", "the implicit scheme's degree k is "
                             "manager.extrapolation, for both sides of the joint; remove it")
        if manager.corrects:
            problems.add("manager.correction", "energy correction belongs to the explicit scheme; the implicit "
                         "scheme holds the joint itself")
        if manager.implicit is not None:
            for joint in joints:
                try:
                    check_supported(manager.implicit.coupling_method(), DECOMPOSITIONS[joint.settings.decomposition])
                except ValueError as error:
                    problems.add(f"couplings.{joint.name}.decomposition", str(error))
    if outputs is not None and joints and outputs.reference == "analytic":
        problems.add("outputs.reference", "a scene with a rigid joint has no analytic reference here; expected "
                     "'solve_ivp' (the subsystems integrated together, the joint held exactly) or 'none'")


def _check_timing(manager: ManagerSettings, tables: dict, subsystems: dict[str, SubsystemScene],
                  problems: Problems) -> None:
    _whole_ns(manager.macro_step, "manager.macro_step", problems)
    _whole_ns(manager.duration, "manager.duration", problems)
    base = manager.macro_step_ns
    ratios = [s.settings.comm_ratio for s in subsystems.values()] or [1]
    period = base * math.lcm(*ratios)
    if manager.duration_ns % period:
        problems.add("manager.duration", f"expected a multiple of {period * 1e-9:g} s (the macro step times the "
                     f"least common multiple of the communication ratios), got {manager.duration!r} s")
    for sub in subsystems.values():
        key = f"subsystems.{sub.name}.micro_step"
        _whole_ns(sub.settings.micro_step, key, problems)
        comm = base * sub.settings.comm_ratio
        if comm % sub.settings.micro_step_ns:
            problems.add(key, f"expected a divisor of the communication step {comm * 1e-9:g} s, "
                         f"got {sub.settings.micro_step!r} s")


def extrapolation_order(manager: ManagerSettings, subsystem: SubsystemScene) -> int:
    """The Lagrange order of the inputs ``subsystem`` receives (its own, else the scene's)."""
    own = subsystem.settings.extrapolation
    return manager.extrapolation if own is None else own


def check_compensation(manager: ManagerSettings, couplings: dict, subsystems: dict[str, SubsystemScene],
                       problems: Problems) -> None:
    """What the eigenstructure compensator (manager.compensator) needs of a scene's structure."""
    if len(couplings) != 1 or next(iter(couplings.values())).kind != "force_displacement":
        problems.add("manager.compensation", f"expected exactly one force_displacement coupling, got {len(couplings)} "
                     "coupling(s)")
    multi_rate = sorted(s.name for s in subsystems.values() if s.settings.comm_ratio != 1)
    if multi_rate:
        problems.add("manager.compensation", f"expected a single-rate scene (comm_ratio = 1), got comm_ratio != 1 "
                     f"in {', '.join(multi_rate)}")
    orders = sorted({extrapolation_order(manager, s) for s in subsystems.values()})
    if len(orders) > 1:
        problems.add("manager.compensation", f"expected one extrapolation order for every subsystem (one D(s)), "
                     f"got {orders}")
    if manager.corrects:
        problems.add("manager.compensation", "expected no energy correction (manager.correction) with the "
                     "compensator: its discrete correction does not model it")


def _check_couplings(couplings: dict, subsystems: dict[str, SubsystemScene], tables: dict,
                     problems: Problems) -> None:
    seen: dict[str, str] = {}
    for coupling in couplings.values():
        for signal, producer in coupling.producers().items():
            if seen.setdefault(signal, producer) != producer:
                problems.add(f"couplings.{coupling.name}", f"signal {signal!r} would be {producer} but is already "
                             f"{seen[signal]}; name it differently")
        for key, (sub, point) in coupling.sides().items():
            full_key = f"couplings.{coupling.name}.{key}"
            if sub not in tables:
                problems.add(full_key, f"unknown subsystem {sub!r}; expected one of {', '.join(tables)}")
            elif sub in subsystems and point not in subsystems[sub].spec.points:
                problems.add(full_key, f"subsystem {sub!r} has no point {point!r}; expected one of "
                             f"{', '.join(subsystems[sub].spec.points)}")
        if not all(sub in subsystems for sub, _ in coupling.sides().values()):
            continue
        if isinstance(coupling, RigidJoint):
            _check_joint_sides(coupling, subsystems, problems)
        else:
            _check_coupled_models(coupling, subsystems, problems)


def _check_joint_sides(joint: RigidJoint, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """Both points move in as many dimensions as the joint has axes and can be driven as it says."""
    for index, (sub, point) in enumerate(joint.points):
        spec, model = subsystems[sub].spec, MODELS[subsystems[sub].settings.model]
        if point not in spec.points:
            continue
        if model.point_dimension != joint.dimension:
            problems.add(f"couplings.{joint.name}.axes", f"{sub}.{point} moves in {model.point_dimension} "
                         f"dimension(s), the joint has {joint.dimension} axes")
        reason = spec.drive_problem(point, joint.side(index).drive, joint.dimension)
        if reason:
            problems.add(f"couplings.{joint.name}.decomposition", f"{sub}.{point}: {reason}")


def _check_coupled_models(coupling, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """The models on both sides can play their role with signals of this many components."""
    key = f"couplings.{coupling.name}"
    models = {}
    for side, (sub, _) in coupling.sides().items():
        role = side.removesuffix("_side")
        model = models[role] = MODELS[subsystems[sub].settings.model]
        if role not in model.coupling_roles:
            problems.add(f"{key}.{side}", f"model {model.name} cannot be the {role} side of a coupling")
        if coupling.dimension != model.point_dimension:
            problems.add(f"{key}.force", f"model {model.name} of {sub} exchanges {model.point_dimension}-component "
                         f"signals, got {coupling.dimension} (one name, or a list of names per signal)")
    force_model = models["force"]
    if not coupling.effects and not force_model.provides_force:
        problems.add(f"{key}.effects", "expected the coupling element as named effects, e.g. effects.kc = "
                     f"{{ type = \"spring\", stiffness = 100.0 }} (model {force_model.name} computes no coupling force itself)")
    if coupling.effects and force_model.provides_force:
        problems.add(f"{key}.effects", f"model {force_model.name} computes the coupling force itself; remove effects")
    if force_model.starts_at_rest and not hasattr(models["motion"], "rest_state"):
        problems.add(f"{key}.motion_side", f"model {force_model.name} starts in equilibrium with its load; model "
                     f"{models['motion'].name} cannot state the load at rest")
    if coupling.dimension == 1:
        for placed in coupling.effects:
            if placed.effect.free_length != 0.0:
                problems.add(f"{key}.effects.{placed.name.split('.', 1)[1]}.free_length",
                             "expected 0 for points on a line (a free length needs points in the plane)")
