"""Coupling types: how two subsystems are joined and which signals cross the interface.

A coupling turns its scene table into attachments for each side (terminals, input forces, outputs,
the coupling element's effects), the routes of the signals between them and the power bonds whose
residual power the manager monitors. The run loop only sees routes and bonds, so a new coupling type
(displacement–displacement, force–force) is one new class here. ``COUPLINGS`` maps scene names to
classes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from subsystems.effects import PlacedEffect, read_effect
from subsystems.params import Problems, read_table
from subsystems.ports import Attachments, EffectForceOutput, ForceInput, MotionOutput, Terminal


@dataclass(frozen=True)
class Route:
    """Output ``output`` of subsystem ``source`` feeds input ``input`` of subsystem ``target``."""

    source: str
    output: str
    target: str
    input: str


@dataclass(frozen=True)
class Bond:
    """A power bond across the interface: a force and the velocity it works on, as seen by each side.

    ``force`` is computed by ``force_side`` from the received ``velocity_input``; ``motion_side``
    applies the received ``force_input`` (as a reaction, sign −1) and outputs ``velocity``.
    """

    name: str
    force_side: str
    force: str
    velocity_input: str
    motion_side: str
    velocity: str
    force_input: str


@dataclass(frozen=True)
class ForceDisplacementSettings:
    type: Literal["force_displacement"]
    force_side: str  # "<subsystem>.<point>": owns the coupling element, outputs the force (direct feedthrough)
    motion_side: str  # "<subsystem>.<point>": applies the force, outputs displacement and velocity
    force: str  # name of the force signal [N]: force of the coupling element on the force-side point
    displacement: str  # name of the displacement signal [m]
    velocity: str  # name of the velocity signal [m/s]

    def problems(self) -> list[tuple[str, str]]:
        found = []
        for key in ("force_side", "motion_side"):
            value = getattr(self, key)
            if value.count(".") != 1 or not all(value.split(".")):
                found.append((key, f"expected '<subsystem>.<point>', got {value!r}"))
        if not found and self.force_side.split(".")[0] == self.motion_side.split(".")[0]:
            found.append(("motion_side", "expected a different subsystem than force_side"))
        names = (self.force, self.displacement, self.velocity)
        if len(set(names)) != 3:
            found.append(("force", f"signal names must differ, got {names}"))
        return found


class ForceDisplacement:
    """Force–displacement coupling (paper 000 Fig. 2, paper 002 Fig. 8).

    The force side holds the coupling spring–damper between its point and a terminal that moves with
    the received displacement and velocity ``x*, v*`` of the motion side; it outputs
    ``fc = -k (x_f - x*) - c (v_f - v*)`` (for linear elements), which depends on its inputs (direct
    feedthrough). The motion side applies ``-fc*`` and outputs its displacement and velocity.
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
        effect_tables = table.get("effects")
        if not isinstance(effect_tables, dict) or not effect_tables:
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

    def signals(self) -> tuple[str, str, str]:
        s = self.settings
        return (s.force, s.displacement, s.velocity)

    def producers(self) -> dict[str, str]:
        """Each signal and what produces it; couplings sharing a motion side share its signals."""
        s = self.settings
        return {s.force: f"the force of coupling {self.name!r}",
                s.displacement: f"the displacement of {s.motion_side}",
                s.velocity: f"the velocity of {s.motion_side}"}

    def _terminal(self) -> Terminal:
        s = self.settings
        return Terminal(f"{self.name}:{self.settings.motion_side}", f"{s.displacement}*", f"{s.velocity}*")

    def attachments(self) -> dict[str, Attachments]:
        s = self.settings
        terminal = self._terminal()
        return {
            self.force_sub: Attachments(
                terminals=(terminal,),
                force_outputs=(EffectForceOutput(s.force, self.force_point, tuple(e.name for e in self.effects)),),
                effects=tuple((e.name, e.effect, (self.force_point, terminal.name)) for e in self.effects)),
            self.motion_sub: Attachments(
                force_inputs=(ForceInput(f"{s.force}*", self.motion_point, -1.0),),
                motion_outputs=(MotionOutput(self.motion_point, s.displacement, s.velocity),)),
        }

    def monolithic_attachments(self, qualify) -> Attachments:
        """The same element acting directly between the two bodies of a monolithic model.

        ``qualify(subsystem, point)`` gives the monolithic name of a point.
        """
        s = self.settings
        force_point = qualify(self.force_sub, self.force_point)
        motion_point = qualify(self.motion_sub, self.motion_point)
        return Attachments(
            force_outputs=(EffectForceOutput(s.force, force_point, tuple(e.name for e in self.effects)),),
            motion_outputs=(MotionOutput(motion_point, s.displacement, s.velocity),),
            effects=tuple((e.name, e.effect, (force_point, motion_point)) for e in self.effects))

    def routes(self) -> tuple[Route, ...]:
        s = self.settings
        return (Route(self.motion_sub, s.displacement, self.force_sub, f"{s.displacement}*"),
                Route(self.motion_sub, s.velocity, self.force_sub, f"{s.velocity}*"),
                Route(self.force_sub, s.force, self.motion_sub, f"{s.force}*"))

    def bonds(self) -> tuple[Bond, ...]:
        s = self.settings
        return (Bond(self.name, self.force_sub, s.force, f"{s.velocity}*", self.motion_sub, s.velocity, f"{s.force}*"),)


COUPLINGS: dict[str, type] = {cls.kind: cls for cls in (ForceDisplacement,)}
