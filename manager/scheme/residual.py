"""Residual power of a power bond (paper 002 Eqs. 7–9, 12) — the one place it is computed.

With the sign convention of ``subsystems.ports`` (a connection copies a value unchanged): the force
side outputs the force ``f`` its coupling element exerts on the remote point, which moves with the
received velocity ``v*``, so the power leaving the force side through the interface is ``f v*``; the
motion side applies the received ``f*`` to a body moving with ``v``, receiving ``f* v``. This is the
power bond of OSP and of libcosim's ECCO algorithm (input times output on each side). The interface
creates energy at the rate

    δP = (power into the motion side) − (power out of the force side) = f* v − f v*,

which vanishes when nothing is extrapolated (``f* = f``, ``v* = v``). Both inputs are the values the
subsystems actually used at the communication point ``t_{k+1}``: the input polynomials they received
evaluated there (``ũ_{k+1}`` of Eq. 9; for ZOH that is ``u_k``, the paper's choice). With energy
correction, ``f*`` is the force the extrapolation produced, before the correction is added: the
residual measures the interface's own error, and the correction's work is accounted separately.
"""
from __future__ import annotations


def residual_power(force: float, velocity_input: float, force_input: float, velocity: float) -> float:
    """δP [W] of one bond at one communication point; positive when the interface adds energy.

    For a bond in the plane, call it per component and add: the power is a dot product, and the
    vector bond is one power bond (its components are not bonds to be monitored apart).
    """
    return force_input * velocity - force * velocity_input


def residual_power_text(force: str, velocity_input: str, force_input: str, velocity: str) -> str:
    """``residual_power`` as the text of an expression over the four names (a generated loop's:
    ``manager.scheme.compiled``), the same operations in the same order."""
    return f"{force_input} * {velocity} - {force} * {velocity_input}"
