"""Coupling types: how two subsystems are joined and which signals cross the interface.

A coupling turns its scene table into attachments for each side (terminals, input forces, outputs,
the coupling element's effects), the routes of the signals between them and the power bonds whose
residual power the manager monitors. The run loop only sees routes and bonds, so a new coupling type
(displacement–displacement, force–force) is one new class here. ``COUPLINGS`` maps scene names to
classes. A coupling whose inputs the manager computes rather than routes (the coupling variables of a
rigid joint) lists them in ``computed_inputs()``.

A signal is a scalar (one name) or a vector of scalar components (a list of names, e.g. the x and y
components of a point in the plane); every signal of one coupling has the same number of components.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from zencosim.compensation.implicit.decompositions import DECOMPOSITIONS, Decomposition
from zencosim.subsystems.effects import PlacedEffect, read_effect
from zencosim.subsystems.params import Problems, quantity, read_table
from zencosim.subsystems.ports import (
    Attachments,
    EffectForceOutput,
    ForceInput,
    JointSide,
    MotionOutput,
    SignalPort,
    Terminal,
)


@dataclass(frozen=True)
class Route:
    """Output ``output`` of subsystem ``source`` feeds input ``input`` of subsystem ``target``."""

    source: str
    output: str
    target: str
    input: str
    order: int | None = None  # Lagrange order of its extrapolation (None: the target subsystem's)


@dataclass(frozen=True)
class Bond:
    """A power bond across the interface: a force and the velocity it works on, as seen by each side.

    ``force`` is computed by ``force_side`` from the received ``velocity_input``: the force on the motion
    side's point; ``motion_side`` applies the received ``force_input`` as it is and outputs ``velocity``.
    Each is a tuple of component signal names (one for a scalar bond); the power is their dot product.
    """

    name: str
    force_side: str
    force: tuple[str, ...]
    velocity_input: tuple[str, ...]
    motion_side: str
    velocity: tuple[str, ...]
    force_input: tuple[str, ...]


def components(signal: str | tuple[str, ...]) -> tuple[str, ...]:
    """The component names of a scalar (one name) or vector (list of names) signal."""
    return (signal,) if isinstance(signal, str) else signal


def side_problems(settings, first: str, second: str) -> list[tuple[str, str]]:
    """Problems of a coupling's two ``"<subsystem>.<point>"`` keys ``first`` and ``second``: each must
    name a point, and the two points must be in different subsystems."""
    found = []
    for key in (first, second):
        value = getattr(settings, key)
        if value.count(".") != 1 or not all(value.split(".")):
            found.append((key, f"expected '<subsystem>.<point>', got {value!r}"))
    if not found and getattr(settings, first).split(".")[0] == getattr(settings, second).split(".")[0]:
        found.append((second, f"expected a different subsystem than {first}"))
    return found


def starred(names: tuple[str, ...]) -> tuple[str, ...]:
    """Input port names of received signals: ``x2`` arrives as ``x2*``."""
    return tuple(f"{n}*" for n in names)


@dataclass(frozen=True)
class ForceDisplacementSettings:
    type: Literal["force_displacement"]
    force_side: str  # "<subsystem>.<point>": computes the force (direct feedthrough)
    motion_side: str  # "<subsystem>.<point>": applies the force, outputs displacement and velocity
    force: str | tuple[str, ...]  # force signal [N]: force of the coupling element on the motion-side point
    displacement: str | tuple[str, ...]  # displacement signal [m] of the motion-side point ([]: none exchanged)
    velocity: str | tuple[str, ...]  # velocity signal [m/s] of the motion-side point
    domain: Literal["translational", "rotational", "hydraulic", "electrical"] = "translational"  # of the bond
    force_factor: float = 1.0  # a force side that computes the force itself: the bond's force is this × its output

    def problems(self) -> list[tuple[str, str]]:
        found = side_problems(self, "force_side", "motion_side")
        signals = {key: components(getattr(self, key)) for key in ("force", "displacement", "velocity")}
        sizes = {key: len(names) for key, names in signals.items()}
        if sizes["displacement"] == 0:
            del sizes["displacement"]  # checked against the models: only a force side of its own needs none
        if 0 in sizes.values() or len(set(sizes.values())) != 1:
            found.append(("force", "force, displacement and velocity need the same number of components "
                                   f"(one name, or a list of names), got {sizes}"))
        if not (math.isfinite(self.force_factor) and self.force_factor != 0.0):
            found.append(("force_factor", f"expected a finite, nonzero number, got {self.force_factor!r}"))
        names = [n for group in signals.values() for n in group]
        if len(set(names)) != len(names):
            found.append(("force", f"signal names must differ, got {names}"))
        return found


class ForceDisplacement:
    """Force–displacement coupling (paper 000 Fig. 2, paper 002 Figs. 8, 16, 19).

    The force side holds the coupling element (spring–damper) between its point and a terminal that
    moves with the received displacement and velocity ``x*, v*`` of the motion side; it outputs
    the force the element exerts on the motion side's point, ``fc = k (x_f - x*) + c (v_f - v*)`` (for
    linear elements; the element pulls the force-side point with ``-fc``), which depends on its inputs
    (direct feedthrough). The motion side applies ``fc*`` as it receives it (a connection copies a value
    unchanged, as FMI, SSP and OSP define it) and outputs its displacement and velocity. A coupling
    without effects has a force-side model that computes the force itself from its own state and the
    received motion (the hydraulic actuator of paper 002 Eq. 25); it outputs the force on the motion
    side's point too (times ``force_factor``, SSP's linear transformation of the force's connection, for a
    component written with the other sign).

    A bond of another physical domain (``domain``, ``subsystems.ports.DOMAINS``) joins FMUs or Python models
    whose points are of that domain: ``force`` is its effort (torque, pressure, voltage), ``velocity`` its
    flow (angular velocity, volume flow, current), ``displacement`` the flow's integral (angle, volume,
    charge; ``[]`` when the force side needs none, as OSP's ports without "Quasi" exchange none). Residual
    power and energy correction read effort and flow alone, so they hold in every domain.
    """

    kind = "force_displacement"

    def __init__(self, name: str, settings: ForceDisplacementSettings, effects: tuple[PlacedEffect, ...]) -> None:
        self.name = name
        self.settings = settings
        self.effects = effects
        self.force_sub, self.force_point = settings.force_side.split(".")
        self.motion_sub, self.motion_point = settings.motion_side.split(".")

    @classmethod
    def read(cls, name: str, table: dict, key: str, problems: Problems) -> "ForceDisplacement | None":
        before = len(problems)
        settings = read_table(ForceDisplacementSettings, table, key, problems, skip=("effects",))
        effects = []
        effect_tables = table.get("effects", {})
        if not isinstance(effect_tables, dict):
            problems.add(f"{key}.effects", "expected the coupling element as named effects, "
                         "e.g. effects.kc = { type = \"spring\", stiffness = 100.0 }")
            effect_tables = {}
        for effect_name, effect_table in effect_tables.items():
            effect_key = f"{key}.effects.{effect_name}"
            effect = read_effect(effect_table, effect_key, problems)
            if effect is None:
                continue
            if 2 not in effect.endpoint_counts:
                problems.add(f"{effect_key}.type", "expected an effect between two points (spring, damper)")
            elif "bodies" in effect_table:
                problems.add(f"{effect_key}.bodies", "a coupling element connects force_side and motion_side; "
                             "remove bodies")
            effects.append(PlacedEffect(f"{name}.{effect_name}", effect, ()))
        if len(problems) != before:
            return None
        return cls(name, settings, tuple(effects))

    def sides(self) -> dict[str, tuple[str, str]]:
        return {"force_side": (self.force_sub, self.force_point), "motion_side": (self.motion_sub, self.motion_point)}

    @property
    def force(self) -> tuple[str, ...]:
        return components(self.settings.force)

    @property
    def displacement(self) -> tuple[str, ...]:
        return components(self.settings.displacement)

    @property
    def velocity(self) -> tuple[str, ...]:
        return components(self.settings.velocity)

    @property
    def dimension(self) -> int:
        """Number of components of each signal (1 on a line, 2 in the plane)."""
        return len(self.force)

    def signals(self) -> tuple[str, ...]:
        return self.force + self.displacement + self.velocity

    def producers(self) -> dict[str, str]:
        """Each signal and what produces it; couplings sharing a motion side share its signals."""
        s = self.settings
        return ({n: f"the force of coupling {self.name!r}" for n in self.force}
                | {n: f"the displacement of {s.motion_side}" for n in self.displacement}
                | {n: f"the velocity of {s.motion_side}" for n in self.velocity})

    @property
    def exchanges_displacement(self) -> bool:
        return bool(self.displacement)

    def _terminal(self) -> Terminal:
        return Terminal(f"{self.name}:{self.settings.motion_side}", starred(self.displacement), starred(self.velocity),
                        self.force_point)

    def attachments(self) -> dict[str, Attachments]:
        terminal = self._terminal()
        return {
            self.force_sub: Attachments(
                terminals=(terminal,),
                force_outputs=(EffectForceOutput(self.force, self.force_point, tuple(e.name for e in self.effects),
                                                 self.settings.force_factor),),
                effects=tuple((e.name, e.effect, (self.force_point, terminal.name)) for e in self.effects)),
            self.motion_sub: Attachments(
                force_inputs=(ForceInput(starred(self.force), self.motion_point, 1.0),),
                motion_outputs=(MotionOutput(self.motion_point, self.displacement, self.velocity),)),
        }

    def monolithic_attachments(self, qualify) -> Attachments:
        """The same element acting directly between the two bodies of a monolithic model.

        ``qualify(subsystem, point)`` gives the monolithic name of a point.
        """
        force_point = qualify(self.force_sub, self.force_point)
        motion_point = qualify(self.motion_sub, self.motion_point)
        return Attachments(
            force_outputs=(EffectForceOutput(self.force, force_point, tuple(e.name for e in self.effects)),),
            motion_outputs=(MotionOutput(motion_point, self.displacement, self.velocity),),
            effects=tuple((e.name, e.effect, (force_point, motion_point)) for e in self.effects))

    def routes(self) -> tuple[Route, ...]:
        received = ((self.motion_sub, self.displacement, self.force_sub), (self.motion_sub, self.velocity, self.force_sub),
                    (self.force_sub, self.force, self.motion_sub))
        return tuple(Route(source, name, target, f"{name}*") for source, names, target in received for name in names)

    def bonds(self) -> tuple[Bond, ...]:
        return (Bond(self.name, self.force_sub, self.force, starred(self.velocity), self.motion_sub, self.velocity,
                     starred(self.force)),)


@dataclass(frozen=True)
class RigidJointSettings:
    type: Literal["rigid_joint"]
    side_1: str  # "<subsystem>.<point>": the joint force λ acts on it with + (paper 003 Eq. 4, mass 1)
    side_2: str  # "<subsystem>.<point>": λ acts on it with −
    decomposition: Literal["force-force", "force-displacement", "displacement-displacement"] = "force-force"
    axes: tuple[str, ...] = ("x",)  # components of the joint: ["x"] on a line, ["x", "y"] in the plane

    def problems(self) -> list[tuple[str, str]]:
        found = side_problems(self, "side_1", "side_2")
        if len(self.axes) not in (1, 2) or len(set(self.axes)) != len(self.axes):
            found.append(("axes", f"expected one or two distinct axis names, got {list(self.axes)}"))
        return found


class RigidJoint:
    """A rigid joint between points of two subsystems, held by an implicit coupling method (paper 003 §2).

    ``decomposition`` splits it as in §2.1–2.3: force/force (both points driven by the joint force
    ``λ_c``), force/displacement (side 1 by ``λ_c``, side 2 follows the acceleration ``a_1`` of side 1)
    or displacement/displacement (both follow the acceleration ``ã``). The coupling variables are the
    decomposition's (``compensation.implicit.decompositions``), one per axis, computed by the manager
    (``computed_inputs``); each side reports position, velocity, acceleration and joint force of its
    point and the point's inverse effective mass (``subsystems.ports.JointSide``). Port names:
    ``<joint>.<x|v|a|f><side>`` and ``<joint>.Minv<side>``, inputs ``<joint>.<variable>*``, with
    ``_<axis>`` (``_<axis><axis>`` for Minv) on a joint with two axes.
    """

    kind = "rigid_joint"
    effects = ()  # no coupling element: the joint is a constraint

    def __init__(self, name: str, settings: RigidJointSettings) -> None:
        self.name = name
        self.settings = settings
        self.decomposition: Decomposition = DECOMPOSITIONS[settings.decomposition]
        self.points = tuple(tuple(side.split(".")) for side in (settings.side_1, settings.side_2))

    @classmethod
    def read(cls, name: str, table: dict, key: str, problems: Problems) -> "RigidJoint | None":
        settings = read_table(RigidJointSettings, table, key, problems)
        return None if settings is None else cls(name, settings)

    @property
    def dimension(self) -> int:
        """Number of axes of the joint (1 on a line, 2 in the plane)."""
        return len(self.settings.axes)

    def _names(self, stem: str) -> tuple[str, ...]:
        axes = self.settings.axes
        return (f"{self.name}.{stem}",) if len(axes) == 1 else tuple(f"{self.name}.{stem}_{a}" for a in axes)

    def coupling_variables(self) -> tuple[str, ...]:
        """Names of the coupling variables ``e``, variable-major: ``lambda_c_x, lambda_c_y, a_1_x, ...``."""
        return tuple(n for variable in self.decomposition.coupling_variables for n in self._names(variable))

    def side(self, index: int) -> JointSide:
        """Side 1 (index 0) or side 2 (index 1) as attached to its subsystem."""
        number = index + 1
        axes = self.settings.axes
        variable = self.decomposition.coupling_variables[self.decomposition.coupling_index[index]]
        inverse_masses = ((f"{self.name}.Minv{number}",) if len(axes) == 1
                          else tuple(f"{self.name}.Minv{number}_{a}{b}" for a in axes for b in axes))
        return JointSide(self.points[index][1], 1.0 if index == 0 else -1.0, self.decomposition.drives[index],
                         tuple(f"{n}*" for n in self._names(variable)), self._names(f"x{number}"),
                         self._names(f"v{number}"), self._names(f"a{number}"), self._names(f"f{number}"), inverse_masses)

    def sides(self) -> dict[str, tuple[str, str]]:
        return {"side_1": self.points[0], "side_2": self.points[1]}

    def signals(self) -> tuple[str, ...]:
        return tuple(name for i in (0, 1) for part in ("positions", "velocities", "accelerations", "forces")
                     for name in getattr(self.side(i), part))

    def producers(self) -> dict[str, str]:
        return {name: f"an output of joint {self.name!r}" for name in self.signals()}

    def attachments(self) -> dict[str, Attachments]:
        return {self.points[i][0]: Attachments(joint_sides=(self.side(i),)) for i in (0, 1)}

    def computed_inputs(self) -> tuple[tuple[str, str], ...]:
        """``(subsystem, input port)`` of every coupling variable: the manager computes them."""
        return tuple((self.points[i][0], port) for i in (0, 1) for port in self.side(i).inputs)

    def routes(self) -> tuple[Route, ...]:
        return ()

    def bonds(self) -> tuple[Bond, ...]:
        return ()


@dataclass(frozen=True)
class SignalSettings:
    type: Literal["signal"]
    output: str  # "<subsystem>.<variable>": an output variable of an FMU or a Python model
    input: str  # "<subsystem>.<variable>": the input variable that receives its value
    factor: float = 1.0  # SSP's linear transformation: the input receives factor × output + offset (SI)
    offset: float = 0.0
    extrapolation: int | None = field(default=None, metadata=quantity("", minimum=0, maximum=2))  # its own
    # Lagrange order (ZOH 0, FOH 1, SOH 2; None: the receiving subsystem's); Integer and Boolean: 0

    def problems(self) -> list[tuple[str, str]]:
        found = [(key, f"expected a finite number, got {getattr(self, key)!r}") for key in ("factor", "offset")
                 if not math.isfinite(getattr(self, key))]
        for key in ("output", "input"):
            value = getattr(self, key)
            if value.count(".") < 1 or not all(value.split(".", 1)):
                found.append((key, f"expected '<subsystem>.<variable>', got {value!r}"))
        return found


class SignalConnection:
    """A plain signal connection: an output variable of one external model copied into an input variable of
    another at every communication point, unchanged (FMI, SSP and OSP's connection), in no power bond.

    The signal is named after the coupling; the receiving input is ``<coupling>*``. Its value travels in
    SI (each component converts at its boundary, ``subsystems.models.external.model``), and both ends must
    be of one quantity (or both without unit). A linear transformation (``factor``, ``offset``) is applied
    where the value leaves its source, so the signal, as exchanged and recorded, is what the input receives.
    It is exchanged, extrapolated (with the connection's own ``extrapolation`` order, if it has one) and
    recorded like every other signal; an output that depends on its inputs at the same instant takes part
    in the initialisation order and its loops are found as for any feedthrough output.
    """

    kind = "signal"
    effects = ()
    dimension = 1

    def __init__(self, name: str, settings: SignalSettings) -> None:
        self.name = name
        self.settings = settings
        self.source, self.output = settings.output.split(".", 1)
        self.target, self.input = settings.input.split(".", 1)

    @classmethod
    def read(cls, name: str, table: dict, key: str, problems: Problems) -> "SignalConnection | None":
        settings = read_table(SignalSettings, table, key, problems)
        return None if settings is None else cls(name, settings)

    def sides(self) -> dict[str, tuple[str, str]]:
        """``output`` and ``input``: (subsystem, variable)."""
        return {"output": (self.source, self.output), "input": (self.target, self.input)}

    def signals(self) -> tuple[str, ...]:
        return (self.name,)

    def producers(self) -> dict[str, str]:
        return {self.name: f"the output {self.settings.output}"}

    def attachments(self) -> dict[str, Attachments]:
        s = self.settings
        source = Attachments(signal_outputs=(SignalPort(self.name, self.output, s.factor, s.offset),))
        target = Attachments(signal_inputs=(SignalPort(f"{self.name}*", self.input),))
        if self.source == self.target:
            return {self.source: source + target}
        return {self.source: source, self.target: target}

    def routes(self) -> tuple[Route, ...]:
        return (Route(self.source, self.name, self.target, f"{self.name}*", self.settings.extrapolation),)

    def bonds(self) -> tuple[Bond, ...]:
        return ()


COUPLINGS: dict[str, type] = {cls.kind: cls for cls in (ForceDisplacement, RigidJoint, SignalConnection)}
