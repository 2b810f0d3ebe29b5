"""SI units as exponents of the base units, so that ``N``, ``kg.m/s2`` and ``kg*m/s^2`` compare equal.

A unit string is a product of factors separated by ``.``, ``*`` or `` `` and divided by ``/``; a factor
is a base unit (``kg m s A K mol cd rad``) or a coherent derived unit (``N J W Pa Hz C V``) with an
optional integer exponent (``s2``, ``s^2``, ``s^-1``), or ``1``. Prefixed and non-SI units (``mm``,
``km/h``, ``g``, ``bar``, ``deg``) are not SI here: zencosim exchanges SI values only, so a port in
them is a mistake to report, not a value to convert. FMI model descriptions state a unit's base-unit
exponents and its factor and offset; it is SI when the factor is 1 and the offset 0.
"""
from __future__ import annotations

import re

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
Exponents = tuple[int, ...]  # one per BASE unit

_DERIVED: dict[str, dict[str, int]] = {
    "N": {"kg": 1, "m": 1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
    "Pa": {"kg": 1, "m": -1, "s": -2},
    "Hz": {"s": -1},
    "C": {"A": 1, "s": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
}
_FACTOR = re.compile(r"^([A-Za-z]+)\^?(-?\d+)?$")


class UnitError(ValueError):
    """A unit that is not a coherent SI unit."""


def exponents(unit: str) -> Exponents:
    """The base-unit exponents of an SI unit string; :class:`UnitError` when it is not one."""
    text = unit.strip()
    if not text:
        raise UnitError("no unit")
    numerator, _, denominator = text.partition("/")
    if "/" in denominator:
        raise UnitError(f"{unit!r}: more than one '/'")
    total = dict.fromkeys(BASE, 0)
    for part, sign in ((numerator, 1), (denominator, -1)):
        for factor in filter(None, re.split(r"[.* ]+", part)):
            if factor == "1":
                continue
            match = _FACTOR.match(factor)
            if match is None:
                raise UnitError(f"{unit!r}: cannot read {factor!r}")
            name, power = match.group(1), int(match.group(2) or 1)
            if name in BASE:
                total[name] += sign * power
            elif name in _DERIVED:
                for base, exponent in _DERIVED[name].items():
                    total[base] += sign * power * exponent
            else:
                raise UnitError(f"{unit!r}: {name!r} is not an SI unit (expected one of "
                                f"{', '.join(BASE + tuple(_DERIVED))}, without prefixes)")
    return tuple(total[name] for name in BASE)


def describe(value: Exponents) -> str:
    """``kg m s-2``-style text of base-unit exponents (``1`` for a dimensionless quantity)."""
    return " ".join(name if e == 1 else f"{name}{e}" for name, e in zip(BASE, value) if e) or "1"


_RAD = BASE.index("rad")


def replaceable(declared: Exponents, stated: Exponents) -> bool:
    """Whether a scene's unit (``stated``) may replace the unit a component declares: when the declared one is
    dimensionless (``1``, pint's ``dimensionless``), or differs from the scene's only in the radian, which the
    component leaves out (the radian is m/m in SI: pint writes ``radian / second`` with ``rad="0"``). Any other
    declared unit is the component's word on its quantity (an equal one needs no replacing)."""
    if declared == stated:
        return False
    if not any(declared):
        return True
    others = [i for i in range(len(BASE)) if i != _RAD]
    return declared[_RAD] == 0 and all(declared[i] == stated[i] for i in others)


def unit_contradiction(name: str, kind: str, declared: str, declared_exponents: Exponents, stated: str,
                       stated_exponents: Exponents) -> str:
    """Why a scene's unit cannot stand for the one a component declares (neither the same quantity nor a
    replaceable one)."""
    return (f"{name}: the {kind} declares [{declared}] ({describe(declared_exponents)}), the scene [{stated}] "
            f"({describe(stated_exponents)}): not the same quantity (a scene's unit replaces a declared one only "
            "where that is dimensionless, or lacks only the radian)")
