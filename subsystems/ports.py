"""Ports: the named, unit-carrying signals a subsystem exchanges, and how couplings attach to a model.

Sign convention of power through a port (the one place it is stated): a connection copies an output's
value into the input unchanged, as FMI, SSP and OSP define it. The force signal of a power bond is the
force that acts on the receiving (motion) side's point, which that side applies as it is; the force
side exerts it on the remote point and feels its reaction ``−f`` on its own. The power that flows
*into* a subsystem through a force input is ``force · velocity`` of the point the force is applied to,
and the power that leaves the force side is its force output times the velocity it received (a dot
product for a point in the plane, whose signals have one port per component). Residual power is
computed from these ports by :func:`manager.scheme.residual.residual_power` only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Quantity = Literal["position", "velocity", "acceleration", "force", "inverse_mass", "energy", "angle",
                   "angular_velocity", "torque", "volume", "volume_flow", "pressure", "charge", "current", "voltage",
                   "signal"]

UNITS: dict[str, str] = {"position": "m", "velocity": "m/s", "acceleration": "m/s^2", "force": "N",
                         "inverse_mass": "1/kg", "energy": "J", "angle": "rad", "angular_velocity": "rad/s",
                         "torque": "N.m", "volume": "m3", "volume_flow": "m3/s", "pressure": "Pa", "charge": "C",
                         "current": "A", "voltage": "V"}


@dataclass(frozen=True)
class Domain:
    """A physical domain of power bonds: the power through a port is effort × flow (the sign convention
    above, with the effort in place of the force); the displacement is the flow's integral."""

    effort: Quantity
    flow: Quantity
    displacement: Quantity


# a new domain is a row here: bonds, residual power and energy correction read effort and flow only
DOMAINS: dict[str, Domain] = {
    "translational": Domain("force", "velocity", "position"),
    "rotational": Domain("torque", "angular_velocity", "angle"),
    "hydraulic": Domain("pressure", "volume_flow", "volume"),
    "electrical": Domain("voltage", "current", "charge"),
}


@dataclass(frozen=True)
class Port:
    """One scalar signal of a subsystem, in SI units."""

    name: str
    quantity: Quantity
    feedthrough: bool = False  # an output that depends on the inputs at the same instant
    signal_unit: str | None = None  # the SI unit of a "signal": any other quantity (a component's variable)
    depends_on: tuple[str, ...] | None = None  # the inputs a feedthrough output depends on (None: all of them)
    # feedthrough only by default: the component does not say what the output depends on (an FMU output without
    # ``dependencies``, which FMI reads as every input); initialised as libcosim does (run_plan._init_rounds)
    undeclared: bool = False
    discrete: bool = False  # an Integer or Boolean variable's: held over a step (extrapolated with order 0)

    @property
    def unit(self) -> str:
        return self.signal_unit if self.quantity == "signal" else UNITS[self.quantity]

    def direct_inputs(self, inputs: tuple["Port", ...]) -> tuple[int, ...]:
        """Indices, among ``inputs``, of the inputs this output depends on at the same instant."""
        if not self.feedthrough:
            return ()
        return tuple(j for j, p in enumerate(inputs) if self.depends_on is None or p.name in self.depends_on)


@dataclass(frozen=True)
class Terminal:
    """A remote point seen from inside a subsystem: its exchanged position and velocity inputs.

    Effects can act between a local point and a terminal (the coupling element of a force–displacement
    coupling, paper 000 Fig. 2); the terminal moves as the extrapolated inputs say. A vector signal
    (a point in the plane) has one port per component, in the order the scene lists them.
    """

    name: str
    position_inputs: tuple[str, ...]
    velocity_inputs: tuple[str, ...]
    at: str | None = None  # the local point whose coupling receives this motion (an external model maps it there)


@dataclass(frozen=True)
class ForceInput:
    """An input force (one port per component) applied to a local point, multiplied by ``sign`` (+1 for
    the force of a power bond, which arrives as the force on this point)."""

    ports: tuple[str, ...]
    point: str
    sign: float


@dataclass(frozen=True)
class MotionOutput:
    """Outputs the position and velocity (one port per component) of a local point."""

    point: str
    position_ports: tuple[str, ...]
    velocity_ports: tuple[str, ...]


@dataclass(frozen=True)
class EffectForceOutput:
    """Outputs the force (one port per component) that the named effects, acting between a local point
    and the remote one, exert on the remote point: the reaction of their force on the local ``point``.

    With no effects named, the model itself provides the force (a force-side model whose coupling force
    is part of its own physics, e.g. a hydraulic actuator), also as the force on the remote point."""

    ports: tuple[str, ...]
    point: str
    effects: tuple[str, ...]
    factor: float = 1.0  # a model that provides the force itself: the bond's force is factor × its output


@dataclass(frozen=True)
class RestState:
    """The state of a coupling point of the motion side when the whole system starts at rest: its
    position (one value per component) and the coupling force (the bond's force signal: the force on
    the motion side's point) that holds the motion side in static equilibrium there. Given to force-side models that
    start in equilibrium with their load (``starts_at_rest``)."""

    point: str
    position: tuple[float, ...]
    force: tuple[float, ...]


@dataclass(frozen=True)
class RelayedForce:
    """Adds to force output ``port`` the force that ``effects`` exert on ``terminal`` (a remote body on a line).

    The remote subsystem applies the value it receives multiplied by ``sign`` (its ``ForceInput``
    sign), so the force enters the output divided by ``sign``: that is how a non-collocated
    compensation term joins the coupling force (paper 000 Eqs. 37–40, docs/compensation.md).
    """

    port: str
    terminal: str
    effects: tuple[str, ...]
    sign: float


@dataclass(frozen=True)
class JointSide:
    """One side of a rigid joint at a local point (paper 003 §2): how the point is driven and what it reports.

    ``drive = "force"``: the inputs are the joint force ``λ*`` (one port per axis), applied to the point
    as ``sign λ*`` (Eqs. 7a, 7b). ``drive = "displacement"``: the inputs are the acceleration ``ã*`` the
    point must follow (a rheonomic constraint on acceleration level, Eqs. 33b, 57a, 57b); the model
    computes the force the point needs for it. Outputs per axis: position, velocity and acceleration of
    the point and the joint force in the sign of side 1, ``f = sign × (force of the joint on the point)``
    (``λ*`` itself when force-driven, the multiplier ``μ`` when displacement-driven); then the point's
    inverse effective mass ``G M⁻¹ Gᵀ`` (axes × axes, row-major), the weight of the projection step.
    """

    point: str
    sign: float  # +1 on side 1, -1 on side 2 (paper 003 Eq. 4)
    drive: Literal["force", "displacement"]
    inputs: tuple[str, ...]
    positions: tuple[str, ...]
    velocities: tuple[str, ...]
    accelerations: tuple[str, ...]
    forces: tuple[str, ...]
    inverse_masses: tuple[str, ...]


@dataclass(frozen=True)
class SignalPort:
    """A port of a signal connection on a component variable of an external model: the output ``port``
    publishes the variable's value, or the input ``port`` (``<signal>*``) sets it (SI at the port; the
    component's own unit inside)."""

    port: str
    variable: str
    factor: float = 1.0  # an output's linear transformation: the port carries factor × value + offset
    offset: float = 0.0


@dataclass(frozen=True)
class Attachments:
    """Everything couplings add to one subsystem: terminals, input forces, outputs, coupling effects."""

    terminals: tuple[Terminal, ...] = ()
    force_inputs: tuple[ForceInput, ...] = ()
    motion_outputs: tuple[MotionOutput, ...] = ()
    force_outputs: tuple[EffectForceOutput, ...] = ()
    effects: tuple = ()  # (name, effect, endpoints) triples added by couplings; endpoints name bodies/terminals
    rest_states: tuple[RestState, ...] = ()
    relayed_forces: tuple[RelayedForce, ...] = ()
    joint_sides: tuple[JointSide, ...] = ()
    signal_outputs: tuple[SignalPort, ...] = ()  # signal connections (external models only)
    signal_inputs: tuple[SignalPort, ...] = ()

    def __add__(self, other: "Attachments") -> "Attachments":
        """Both sets of attachments; an output two couplings share (one motion side) appears once."""
        return Attachments(*(a + tuple(x for x in b if x not in a) for a, b in zip(self._parts(), other._parts())))

    def _parts(self) -> tuple:
        return (self.terminals, self.force_inputs, self.motion_outputs, self.force_outputs, self.effects,
                self.rest_states, self.relayed_forces, self.joint_sides, self.signal_outputs, self.signal_inputs)
