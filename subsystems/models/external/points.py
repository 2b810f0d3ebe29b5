"""The points of an external model: which of its variables play which coupling role at each point.

A scene names, per point, the component's variables (``points.<point> = { role = "variable", … }``,
a list of names for a vector signal, one per component). A coupling attached to the point uses the
roles its side needs:

============================  ============================================================  =========  ========
role                          meaning                                                       causality  quantity
============================  ============================================================  =========  ========
``force``                     force of the coupling element on the other side's point       output     force
                              (force side; the reaction acts on this point)
``position_input``            position of the other side, received (force side)              input      position
``velocity_input``            velocity of the other side, received (force side)              input      velocity
``force_input``               force applied to the point (motion side; joint, force drive)  input      force
``acceleration_input``        acceleration the point follows (joint, displacement drive)    input      accel.
``position``, ``velocity``    motion of the point (motion side; joint side)                 output     …
``acceleration``              acceleration of the point (joint side)                        output     accel.
``joint_force``               force the joint exerts on the point (displacement drive;      output     force
                              with force drive it is the applied force and may be left out)
``inverse_mass``              the point's inverse effective mass (joint side; a variable    output     1/kg
                              or a number)
============================  ============================================================  =========  ========

A connection copies a value unchanged, as FMI, SSP and OSP define it: a received force is the force
that acts on the component's point (a force-driven joint side's input is applied with the side's sign).

A point of another physical domain (``domain = "rotational"``, ``"hydraulic"``, ``"electrical"``,
``subsystems.ports.DOMAINS``) maps the same roles onto that domain's quantities: ``force`` and
``force_input`` are the effort (torque, pressure, voltage), ``velocity`` and ``velocity_input`` the flow
(angular velocity, volume flow, current), ``position`` and ``position_input`` the displacement (angle,
volume, charge). Joint roles are translational only.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal

from zencosim.subsystems.ports import DOMAINS

ROLES: dict[str, tuple[str, str]] = {  # role -> (causality, quantity)
    "force": ("output", "force"),
    "position_input": ("input", "position"),
    "velocity_input": ("input", "velocity"),
    "force_input": ("input", "force"),
    "acceleration_input": ("input", "acceleration"),
    "position": ("output", "position"),
    "velocity": ("output", "velocity"),
    "acceleration": ("output", "acceleration"),
    "joint_force": ("output", "force"),
    "inverse_mass": ("output", "inverse_mass"),
}
DOMAIN_PARTS = {"force": "effort", "force_input": "effort", "velocity": "flow", "velocity_input": "flow",
                "position": "displacement", "position_input": "displacement"}  # bond roles -> Domain fields


@dataclass(frozen=True)
class PointMap:
    """The component variables of one point, by role (see the module text)."""

    force: str | tuple[str, ...] | None = None
    position_input: str | tuple[str, ...] | None = None
    velocity_input: str | tuple[str, ...] | None = None
    force_input: str | tuple[str, ...] | None = None
    acceleration_input: str | tuple[str, ...] | None = None
    position: str | tuple[str, ...] | None = None
    velocity: str | tuple[str, ...] | None = None
    acceleration: str | tuple[str, ...] | None = None
    joint_force: str | tuple[str, ...] | None = None
    inverse_mass: str | float | tuple[str, ...] | None = None  # a variable, or a constant [1/kg] on a line
    domain: Literal["translational", "rotational", "hydraulic", "electrical"] = "translational"

    def quantity(self, role: str) -> str:
        """The quantity of ``role`` at this point: a bond role's in the point's domain, else the role's own."""
        part = DOMAIN_PARTS.get(role)
        return ROLES[role][1] if part is None else getattr(DOMAINS[self.domain], part)

    def variables(self, role: str) -> tuple[str, ...]:
        """The variable names of ``role`` (one per component; empty when the role is not mapped)."""
        value = getattr(self, role)
        if value is None or isinstance(value, float):
            return ()
        return (value,) if isinstance(value, str) else value

    def roles(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self) if f.name != "domain" and getattr(self, f.name) is not None)

    @property
    def dimension(self) -> int:
        """Components of the point's signals: 1 on a line, 2 in the plane."""
        sizes = {len(self.variables(role)) for role in self.roles()} - {0}
        return sizes.pop() if len(sizes) == 1 else 1

    def problems(self) -> list[tuple[str, str]]:
        found = []
        if not self.roles():
            found.append(("force", f"expected at least one role: {', '.join(ROLES)}"))
        for role in self.roles():
            if getattr(self, role) == ():
                found.append((role, "expected a variable name, or a list of one per component, got an empty list"))
        sizes = {role: len(self.variables(role)) for role in self.roles() if self.variables(role)}
        if len(set(sizes.values())) > 1:
            found.append(("force", f"every role of a point needs as many variables (one per component), got {sizes}"))
        if isinstance(self.inverse_mass, float) and self.inverse_mass <= 0.0:
            found.append(("inverse_mass", f"expected a positive number [1/kg], got {self.inverse_mass!r}"))
        return found

    def can_drive(self, drive: str) -> str | None:
        """Why the point cannot be a joint side driven by ``drive`` (None: it can)."""
        needed = ["position", "velocity", "acceleration", "inverse_mass"]
        needed += ["force_input"] if drive == "force" else ["acceleration_input", "joint_force"]
        missing = [role for role in needed if getattr(self, role) is None]
        if self.domain != "translational":
            return f"a joint side is translational; the point is {self.domain}"
        return f"a joint side with {drive} drive needs the roles {', '.join(missing)}" if missing else None
