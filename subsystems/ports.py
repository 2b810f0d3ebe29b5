"""Ports: the named, unit-carrying signals a subsystem exchanges, and how couplings attach to a model.

Sign convention of power through a port (the one place it is stated): a force port carries the force
that a coupling element exerts on the body it acts on; the power that flows *into* a subsystem
through a force input is ``force * velocity`` of the body the force is applied to. Residual power is
computed from these ports by :func:`manager.residual.residual_power` only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Quantity = Literal["position", "velocity", "force", "energy"]

UNITS: dict[str, str] = {"position": "m", "velocity": "m/s", "force": "N", "energy": "J"}


@dataclass(frozen=True)
class Port:
    """One scalar signal of a subsystem, in SI units."""

    name: str
    quantity: Quantity
    feedthrough: bool = False  # an output that depends on the inputs at the same instant

    @property
    def unit(self) -> str:
        return UNITS[self.quantity]


@dataclass(frozen=True)
class Terminal:
    """A remote body seen from inside a subsystem: its exchanged position and velocity inputs.

    Effects can act between a local body and a terminal (the coupling element of a force–displacement
    coupling, paper 000 Fig. 2); the terminal moves as the extrapolated inputs say.
    """

    name: str
    position_input: str
    velocity_input: str


@dataclass(frozen=True)
class ForceInput:
    """An input force applied to a local body, multiplied by ``sign`` (−1 for the reaction of a coupling force)."""

    port: str
    body: str
    sign: float


@dataclass(frozen=True)
class MotionOutput:
    """Outputs the position and velocity of a local body."""

    body: str
    position_port: str
    velocity_port: str


@dataclass(frozen=True)
class EffectForceOutput:
    """Outputs the total force that the named effects exert on a local body."""

    port: str
    body: str
    effects: tuple[str, ...]


@dataclass(frozen=True)
class Attachments:
    """Everything couplings add to one subsystem: terminals, input forces, outputs, coupling effects."""

    terminals: tuple[Terminal, ...] = ()
    force_inputs: tuple[ForceInput, ...] = ()
    motion_outputs: tuple[MotionOutput, ...] = ()
    force_outputs: tuple[EffectForceOutput, ...] = ()
    effects: tuple = ()  # (name, effect, endpoints) triples added by couplings; endpoints name bodies/terminals

    def __add__(self, other: "Attachments") -> "Attachments":
        """Both sets of attachments; an output two couplings share (one motion side) appears once."""
        return Attachments(*(a + tuple(x for x in b if x not in a) for a, b in zip(self._parts(), other._parts())))

    def _parts(self) -> tuple:
        return (self.terminals, self.force_inputs, self.motion_outputs, self.force_outputs, self.effects)
