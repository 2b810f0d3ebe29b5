"""Checks of a scene that span its tables: timing, scheme and couplings, compensation.

Each check adds what it finds to ``problems`` (file and dotted key); ``manager.scene.load`` collects
every problem of a scene before it raises.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

from zencosim.compensation.implicit.coupling_laws import check_supported
from zencosim.compensation.implicit.decompositions import DECOMPOSITIONS
from zencosim.manager.scene.couplings import RigidJoint, SignalConnection
from zencosim.manager.scene.settings import ManagerSettings, OutputSettings, SubsystemScene, extrapolation_order
from zencosim.manager.scene.times import NotATime, nanoseconds
from zencosim.subsystems.params import Problems


def check_scheme(manager: ManagerSettings, outputs: OutputSettings | None, couplings: dict,
                  subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """Rigid joints need the implicit scheme, which handles one rigid joint, single-rate, with the scene's
    extrapolation order as k and no energy correction (paper 003 §2)."""
    joints = [c for c in couplings.values() if isinstance(c, RigidJoint)]
    if manager.scheme == "gauss-seidel":
        _check_gauss_seidel(manager, subsystems, problems)
    elif manager.order:
        problems.add("manager.order", f"the order subsystems step in belongs to manager.scheme = 'gauss-seidel', "
                     f"got {manager.scheme!r}: remove it")
    if manager.scheme != "implicit":
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
            if not sub.traits.can_save_state:
                problems.add(f"subsystems.{sub.name}.model", f"the implicit scheme repeats every macro-step from a saved "
                             f"state; {_component(sub)} cannot save and restore its state (FMI canGetAndSetFMUstate)")
            projects = manager.implicit is not None and manager.implicit.coupling_method().projects_states
            if projects and not sub.traits.can_project:
                problems.add(f"subsystems.{sub.name}.model", f"the projection method moves the joint's points; "
                             f"{_component(sub)} cannot be moved by zencosim: expected another manager.implicit.method")
        if manager.corrects:
            problems.add("manager.correction", "energy correction belongs to the explicit scheme; the implicit "
                         "scheme holds the joint itself")
        if manager.implicit is not None:
            for joint in joints:
                try:
                    check_supported(manager.implicit.coupling_method(), DECOMPOSITIONS[joint.settings.decomposition])
                except ValueError as error:
                    problems.add(f"couplings.{joint.name}.decomposition", str(error))
    if outputs is not None and outputs.reference == "solve_ivp":
        for sub in subsystems.values():
            if sub.traits.advances_itself:
                problems.add("outputs.reference", f"'solve_ivp' integrates the subsystems' equations together; "
                             f"{_component(sub)} of {sub.name} advances itself and gives none: expected 'none'")
    if outputs is not None and joints and outputs.reference == "analytic":
        problems.add("outputs.reference", "a scene with a rigid joint has no analytic reference here; expected "
                     "'solve_ivp' (the subsystems integrated together, the joint held exactly) or 'none'")


def _check_gauss_seidel(manager: ManagerSettings, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """The Gauss–Seidel scheme here: without energy correction (derived for Jacobi; the compensator:
    ``check_compensation``), ``manager.order`` naming every subsystem once when given."""
    if manager.corrects:
        problems.add("manager.correction", "energy correction (paper 002) is derived for the Jacobi scheme; expected "
                     "it disabled with manager.scheme = 'gauss-seidel'")
    if manager.order:
        unknown = [name for name in manager.order if name not in subsystems]
        repeated = sorted({name for name in manager.order if manager.order.count(name) > 1})
        missing = [name for name in subsystems if name not in manager.order]
        for what, names in (("no such subsystem", unknown), ("named twice", repeated), ("missing", missing)):
            if names:
                problems.add("manager.order", f"{what}: {', '.join(names)}; expected every subsystem once "
                             f"({', '.join(subsystems)})")


def check_step_control(manager: ManagerSettings, couplings: dict, subsystems: dict[str, SubsystemScene],
                       problems: Problems) -> None:
    """What the energy-controlled macro-step (``manager.scheme.energy_step``) runs: the Jacobi scheme, no corrector,
    not paced, at least one power bond, components that can step by varying steps; its step sizes
    whole multiples of ``manager.macro_step`` with ``min_step_size <= step_size <= max_step_size`` (libcosim's
    checks)."""
    if manager.step_control != "energy":
        return
    why = "with manager.step_control = 'energy'"
    if manager.scheme != "jacobi":
        problems.add("manager.scheme", f"expected 'jacobi' {why} (the step control runs the Jacobi scheme), "
                     f"got {manager.scheme!r}")
    if manager.realtime:
        problems.add("manager.realtime", f"expected it off {why}: real time paces a fixed macro-step")
    if manager.corrects:
        problems.add("manager.correction", f"expected it off {why}: energy correction is derived for a fixed "
                     "macro-step")
    if manager.compensation != "none":
        problems.add("manager.compensation", f"expected 'none' {why}: the compensator is designed for one macro-step")
    if not any(coupling.bonds() for coupling in couplings.values()):
        problems.add("manager.step_control", "'energy' controls the step by the residual energy of the power bonds; "
                     "this scene has none")
    for sub in subsystems.values():
        if not sub.traits.variable_step:
            problems.add(f"subsystems.{sub.name}.fmu", f"{_component(sub)} declares a fixed communication step "
                         f"(canHandleVariableCommunicationStepSize false): it cannot take the varying macro-steps of "
                         f"manager.step_control = 'energy'")
    control = manager.energy_control
    if control is None:
        return
    try:
        base = manager.macro_step_ns
    except NotATime:  # check_timing says why
        return
    sizes = {}
    for name in ("step_size", "min_step_size", "max_step_size"):
        seconds = getattr(control, name)
        if seconds is None:
            continue
        key = f"manager.energy_control.{name}"
        count = _whole_ns(seconds, key, problems)
        if count is not None and count % base:
            problems.add(key, f"expected a whole multiple of manager.macro_step ({manager.macro_step!r} s): every "
                         f"macro-step is one, got {seconds!r} s")
        sizes[name] = seconds
    low = sizes.get("min_step_size", manager.macro_step)
    first = sizes.get("step_size", low)
    high = sizes.get("max_step_size")
    if high is not None and not low <= first <= high:
        problems.add("manager.energy_control", f"expected min_step_size <= step_size <= max_step_size, got "
                     f"{low!r}, {first!r}, {high!r} s")
    if control.min_change_rate > control.max_change_rate:
        problems.add("manager.energy_control", f"expected min_change_rate <= max_change_rate, got "
                     f"{control.min_change_rate!r} > {control.max_change_rate!r}")


def check_timing(manager: ManagerSettings, tables: dict, subsystems: dict[str, SubsystemScene],
                  problems: Problems) -> None:
    """Every time a whole number of nanoseconds, at least one macro-step period, communication steps that
    micro-steps divide."""
    _whole_ns(manager.timeout, "manager.timeout", problems, whole=False)  # the watchdog counts it in nanoseconds
    before = len(problems)
    times = [(manager.macro_step, "manager.macro_step"), (manager.duration, "manager.duration")]
    times += [(s.settings.micro_step, f"subsystems.{s.name}.micro_step") for s in subsystems.values()]
    for seconds, key in times:
        _whole_ns(seconds, key, problems)
    if len(problems) != before:
        return
    base = manager.macro_step_ns
    ratios = [s.settings.comm_ratio for s in subsystems.values()] or [1]
    period = base * math.lcm(*ratios)
    if manager.duration_ns < period:
        problems.add("manager.duration", f"expected at least one macro-step period, {period * 1e-9:g} s (the macro "
                     f"step times the least common multiple of the communication ratios), got {manager.duration!r} s")
    elif manager.duration_ns % period:
        problems.add("manager.duration", f"expected a multiple of {period * 1e-9:g} s (the macro step times the "
                     f"least common multiple of the communication ratios), got {manager.duration!r} s")
    for sub in subsystems.values():
        key = f"subsystems.{sub.name}.micro_step"
        comm = base * sub.settings.comm_ratio
        if manager.step_control == "energy" and sub.traits.advances_itself:
            continue  # it takes one step per macro-step, whatever its length (manager.scheme.energy_step)
        if comm % sub.settings.micro_step_ns:
            problems.add(key, f"expected a divisor of the communication step {comm * 1e-9:g} s, "
                         f"got {sub.settings.micro_step!r} s")


def _whole_ns(seconds: float, key: str, problems: Problems, whole: bool = True) -> int | None:
    """A time as whole nanoseconds (``manager.scene.times``; ``whole`` False: rounded), or None with a problem at
    ``key``."""
    try:
        return nanoseconds(seconds, whole)
    except NotATime as error:
        problems.add(key, str(error))
        return None


# a subsystem's and a coupling's name is one segment of a Zenoh key (zencosim/<run>/<subsystem>/y) and of a dotted
# scene key (subsystems.<name>, "<subsystem>.<point>"): letters, digits, "_" and "-", so no key wildcard ("*", "$"),
# separator ("/", "."), hidden chunk ("@"), forbidden character ("?", "#"), space or control character
NAME = re.compile(r"\w[\w-]*")
# a signal's name may also hold "." (a rigid joint's signals are "<joint>.<variable>")
SIGNAL_NAME = re.compile(r"\w[\w.-]*")


def name_problem(name: str, pattern: re.Pattern = NAME) -> str | None:
    """Why ``name`` cannot name a subsystem, coupling (``NAME``) or signal (``SIGNAL_NAME``); None when it can."""
    allowed = "letters, digits, '_', '-'" + (" and '.'" if pattern is SIGNAL_NAME else "")
    if pattern.fullmatch(name) is None:
        return f"expected a name of {allowed}, starting with a letter, digit or '_', got {name!r}"
    return None


def check_names(subsystem_tables: dict, coupling_tables: dict, couplings: dict, problems: Problems) -> None:
    """Subsystem and coupling names, and the signal names a coupling declares (see ``NAME``)."""
    for section, names in (("subsystems", subsystem_tables), ("couplings", coupling_tables)):
        for name in names:
            reason = name_problem(name)
            if reason:
                problems.add(f"{section}.{name}", reason)
    for coupling in couplings.values():
        for signal in coupling.signals():
            reason = name_problem(signal, SIGNAL_NAME)
            if reason:
                problems.add(f"couplings.{coupling.name}", f"signal: {reason}")


def check_compensation(manager: ManagerSettings, couplings: dict, subsystems: dict[str, SubsystemScene],
                       problems: Problems) -> None:
    """What the eigenstructure compensator (manager.analysis.compensator) needs of a scene's structure."""
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
    if manager.scheme == "gauss-seidel":
        problems.add("manager.compensation", "the compensator (paper 000) is designed for the Jacobi scheme; "
                     "expected manager.scheme = 'jacobi' with it")


def check_couplings(couplings: dict, subsystems: dict[str, SubsystemScene], tables: dict,
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
            elif isinstance(coupling, SignalConnection):
                continue
            elif sub in subsystems and point not in subsystems[sub].spec.points:
                problems.add(full_key, f"subsystem {sub!r} has no point {point!r}; expected one of "
                             f"{', '.join(subsystems[sub].spec.points)}")
        if not all(sub in subsystems for sub, _ in coupling.sides().values()):
            continue
        if isinstance(coupling, RigidJoint):
            _check_joint_sides(coupling, subsystems, problems)
        elif isinstance(coupling, SignalConnection):
            _check_signal_ends(coupling, subsystems, problems)
        else:
            _check_coupled_models(coupling, subsystems, problems)


def _check_joint_sides(joint: RigidJoint, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """Both points move in as many dimensions as the joint has axes and can be driven as it says."""
    for index, (sub, point) in enumerate(joint.points):
        spec, traits = subsystems[sub].spec, subsystems[sub].traits
        if point not in spec.points:
            continue
        if traits.point_dimension != joint.dimension:
            problems.add(f"couplings.{joint.name}.axes", f"{sub}.{point} moves in {traits.point_dimension} "
                         f"dimension(s), the joint has {joint.dimension} axes")
        reason = spec.drive_problem(point, joint.side(index).drive, joint.dimension)
        if reason:
            problems.add(f"couplings.{joint.name}.decomposition", f"{sub}.{point}: {reason}")


def _check_signal_ends(signal: SignalConnection, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """Both ends are variables of external models (FMUs, Python models) of the right causality and type, and
    of one quantity."""
    found = {}
    for key, (sub, variable) in signal.sides().items():
        spec = subsystems[sub].spec
        if not hasattr(spec, "variable_problem"):
            problems.add(f"couplings.{signal.name}.{key}", f"model {subsystems[sub].settings.model} of {sub} has no "
                         "variables by name: a signal connection joins variables of FMUs and Python models")
            continue
        reason = spec.variable_problem(variable, key)
        if reason:
            problems.add(f"couplings.{signal.name}.{key}", f"{sub}: {reason}")
        else:
            found[key] = spec.description.variables[variable]
    kinds = {v.kind for v in found.values()}
    if len(found) == 2 and len(kinds) > 1:
        ends = {key: f"{signal.sides()[key][0]}.{v.name} ({v.kind})" for key, v in found.items()}
        problems.add(f"couplings.{signal.name}", f"{ends['output']} feeds {ends['input']}: expected one type")
    elif kinds & {"Integer", "Boolean"} and (signal.settings.extrapolation or 0) > 0:
        problems.add(f"couplings.{signal.name}.extrapolation", f"an {kinds.pop()} is held over a step; expected 0")
    elif kinds & {"Integer", "Boolean"} and (signal.settings.factor != 1.0 or signal.settings.offset != 0.0):
        problems.add(f"couplings.{signal.name}.factor", "a linear transformation applies to Real variables")
    elif len(found) == 2 and found["output"].exponents != found["input"].exponents:
        ends = {key: f"{signal.sides()[key][0]}.{v.name} [{v.unit or 'no unit'}]" for key, v in found.items()}
        problems.add(f"couplings.{signal.name}", f"{ends['output']} feeds {ends['input']}: not the same quantity")


def _check_coupled_models(coupling, subsystems: dict[str, SubsystemScene], problems: Problems) -> None:
    """The models on both sides can play their role with signals of this many components, in the bond's
    domain (built-in models are translational and use the displacement; FMUs and Python models say theirs)."""
    key = f"couplings.{coupling.name}"
    traits, names = {}, {}
    settings = coupling.settings
    for side, (sub, point) in coupling.sides().items():
        role = side.removesuffix("_side")
        model = names[role] = subsystems[sub].settings.model
        found = traits[role] = subsystems[sub].traits
        spec = subsystems[sub].spec
        if role not in found.coupling_roles:
            problems.add(f"{key}.{side}", f"model {model} cannot be the {role} side of a coupling")
        elif hasattr(spec, "role_problem"):
            reason = point in spec.points and spec.role_problem(point, role, settings.domain,
                                                               coupling.exchanges_displacement)
            if reason:
                problems.add(f"{key}.{side}", f"{sub}: {reason}")
        elif settings.domain != "translational":
            problems.add(f"{key}.domain", f"model {model} of {sub} is translational; a {settings.domain} bond joins "
                         "FMUs or Python models")
        elif not coupling.exchanges_displacement:
            problems.add(f"{key}.displacement", f"model {model} of {sub} needs the displacement exchanged; expected "
                         "a signal name")
    if settings.force_factor != 1.0 and not hasattr(subsystems[coupling.force_sub].spec, "role_problem"):
        problems.add(f"{key}.force_factor", f"model {names['force']} outputs the force on the motion side's point "
                     "itself; a factor belongs to an FMU's or Python model's force output")
        if coupling.dimension != found.point_dimension:
            problems.add(f"{key}.force", f"model {model} of {sub} exchanges {found.point_dimension}-component "
                         f"signals, got {coupling.dimension} (one name, or a list of names per signal)")
    force_model = traits["force"]
    if not coupling.effects and not force_model.provides_force:
        problems.add(f"{key}.effects", "expected the coupling element as named effects, e.g. effects.kc = "
                     f"{{ type = \"spring\", stiffness = 100.0 }} (model {names['force']} computes no coupling force itself)")
    if coupling.effects and force_model.provides_force:
        problems.add(f"{key}.effects", f"model {names['force']} computes the coupling force itself; remove effects")
    if force_model.starts_at_rest and not traits["motion"].has_rest_state:
        problems.add(f"{key}.motion_side", f"model {names['force']} starts in equilibrium with its load; model "
                     f"{names['motion']} cannot state the load at rest")
    if coupling.dimension == 1:
        for placed in coupling.effects:
            if placed.effect.free_length != 0.0:
                problems.add(f"{key}.effects.{placed.name.split('.', 1)[1]}.free_length",
                             "expected 0 for points on a line (a free length needs points in the plane)")


def _component(sub: SubsystemScene) -> str:
    """How a message names a subsystem's model: an FMU by its file."""
    fmu = getattr(sub.spec, "source", None)
    return f"FMU {fmu.name}" if isinstance(fmu, Path) else f"model {sub.settings.model}"
