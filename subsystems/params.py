"""Typed parameter tables: read a TOML table into a frozen dataclass, collecting every problem.

A model, an effect or a section of a scene declares its parameters as a dataclass whose fields carry
their type and, in ``metadata``, their unit and bounds::

    @dataclass(frozen=True)
    class Spring:
        stiffness: float = field(metadata=quantity("N/m", minimum=0.0))  # k [N/m]

``read_table`` checks types, bounds, missing and unknown keys and records each problem with the
dotted key it concerns, so that a scene loader can report all of them at once.
"""
from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Literal, get_args, get_origin, get_type_hints


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input: the dotted key it concerns and what was expected."""

    key: str
    reason: str

    def __str__(self) -> str:
        return f"{self.key}: {self.reason}"


class Problems(list):
    """An ordered collection of :class:`Problem`."""

    def add(self, key: str, reason: str) -> None:
        self.append(Problem(key, reason))


@dataclass(frozen=True)
class Plausible:
    """The range of a kind of physical parameter that some physical system has, and why (docs/scenes.md)."""

    unit: str
    minimum: float
    maximum: float
    why: str


NS = 1e-9  # [s] the finest time a scene holds (times travel as signed 64-bit nanoseconds)
LONGEST = 9.2e9  # [s] about (2**63 - 1) ns, the longest duration a scene holds

# Plausibility bounds of the models' and effects' parameters (issue 25). Every bound lies beyond the extreme
# values of real machines (or at a hard physical limit: a discharge coefficient of 1), so that no real system is
# refused, while the products the models form stay far inside float64: at the bounds a force k x, c v or c v^2 is
# at most 4e22 N, an acceleration k x / m at most 2e27 m/s^2, an energy k x^2 or m v^2 at most 1e25 J (float64
# overflows at 1.8e308), and no divisor (a mass, an inertia, a length, an area, a density) is zero or
# subnormal, where 1/x overflows or a mass matrix is singular. Rationale per kind: docs/scenes.md.
PLAUSIBLE: dict[str, Plausible] = {
    "mass": Plausible("kg", 1e-9, 1e9, "a microgram to a million tonnes (the largest ships are 6e8 kg); a mass "
                      "of 0 or 5e-324 makes the mass matrix singular (LinAlgError)"),
    "inertia": Plausible("kg m^2", 1e-12, 1e15, "1 mg at 1 mm (a watch's balance wheel has 1e-10) to a million "
                         "tonnes at 1 km (a ship's yaw inertia is about 1e13)"),
    "length": Plausible("m", 1e-6, 1e6, "a micrometre (a flexure) to 1000 km; a divisor of the links' and the "
                        "cylinder's equations, 5e-324 overflows"),
    "free length": Plausible("m", 0.0, 1e6, "as a length; 0: elements between points on a line"),
    "position": Plausible("m", -1e6, 1e6, "within 1000 km of the origin; float64 resolves 1.2e-10 m there, "
                          "while at 2**63 m its spacing is 2 km and a spring's elongation is lost"),
    "velocity": Plausible("m/s", -1e5, 1e5, "above meteoroids (7.2e4 m/s) and orbital speed (7.9e3 m/s)"),
    "angle": Plausible("rad", -1e4, 1e4, "1600 turns either way; float64 resolves 1.8e-12 rad there, at 2**63 "
                       "rad its spacing is 2048 rad and sin and cos mean nothing"),
    "angular velocity": Plausible("rad/s", -1e5, 1e5, "1e6 rpm, above turbochargers (3e4 rad/s) and "
                                  "ultracentrifuges (1.6e4 rad/s)"),
    "gravity": Plausible("m/s^2", 0.0, 1e3, "up to 100 g, above the Sun's surface (274 m/s^2)"),
    "stiffness": Plausible("N/m", 0.0, 1e12, "0: not built; 1e12 is a 1 m^2 steel block 0.2 m long, above "
                           "machine contacts (1e8 to 1e10); k x at the position bound is 2e18 N"),
    "root stiffness": Plausible("N/m^0.5", 0.0, 1e12, "as a stiffness; κ √η at the position bound is 1.4e15 N"),
    "damping": Plausible("N s/m", 0.0, 1e12, "0: not built; 10 times the critical damping 2√(k m) of the "
                         "stiffest spring on the heaviest mass (6e10)"),
    "quadratic damping": Plausible("N s^2/m^2", 0.0, 1e12, "0: not built; water's drag ½ρ c A on 100 m^2 is "
                                   "5e4; c v² at the velocity bound is 4e22 N"),
    "force": Plausible("N", -1e10, 1e10, "above the largest presses (8e8 N) and rocket thrust (8e7 N)"),
    "frequency": Plausible("Hz", 0.0, 5e8, "the Nyquist frequency of the finest step (1 ns)"),
    "time": Plausible("s", 0.0, LONGEST, "within the longest run (signed 64-bit nanoseconds)"),
    "sweep time": Plausible("s", NS, LONGEST, "a divisor: at least the finest time (1 ns)"),
    "area": Plausible("m^2", 1e-12, 1e2, "a square micrometre (the smallest length squared) to 10 m x 10 m, "
                      "above the largest press pistons (7 m^2); a divisor of the pressure rates"),
    "compressibility": Plausible("1/Pa", 1e-12, 1e-4, "the inverse bulk modulus: 1e4 Pa (a gas at a tenth of an "
                                 "atmosphere) to 1e12 Pa (above diamond, 4.4e11); not negative or 0 (β infinite)"),
    "compressibility slope": Plausible("1/Pa^2", -1e-7, 1e-7, "b = (1 − K') a² / 2 with K' = dβ/dp (6.6 in "
                                       "paper 002, 5 to 12 for liquids) within ±20 of 1 at the largest a"),
    "pressure": Plausible("Pa", 0.0, 1e9, "absolute, up to 10 kbar, above waterjet cutters (6e8 Pa)"),
    "density": Plausible("kg/m^3", 1e-3, 3e4, "air at 48 km altitude to above osmium (2.26e4); a "
                         "divisor of the valve flow"),
    "discharge coefficient": Plausible("", 1e-3, 1.0, "1: an ideal orifice (none exceeds it), typical 0.6 to "
                                       "0.8; below 1e-3 the valve is closed"),
}


def quantity(unit: str, minimum: float | None = None, maximum: float | None = None,
             exclusive_minimum: bool = False, kind: str | None = None) -> dict:
    """Field metadata for a physical quantity: its SI unit and optional bounds.

    With ``kind`` (a key of ``PLAUSIBLE``) the bounds are that kind's plausibility bounds, and a value outside
    them is reported as ``expected 1e-9 ≤ mass ≤ 1e9 [kg], got 0.0``.
    """
    if kind is not None:
        bound = PLAUSIBLE[kind]
        assert unit == bound.unit and minimum is None and maximum is None, (kind, unit)
        return {"unit": unit, "minimum": bound.minimum, "maximum": bound.maximum, "exclusive_minimum": False,
                "kind": kind}
    return {"unit": unit, "minimum": minimum, "maximum": maximum, "exclusive_minimum": exclusive_minimum}


def number_text(value: float) -> str:
    """A bound as people write it: 1e-9, 1e9, 0.5, 850, 3e4, 9.2e9."""
    if isinstance(value, int) or value == 0.0 or 1e-2 <= abs(value) < 1e4:
        return f"{value:.6g}"
    mantissa, exponent = f"{value:.6e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"


def range_text(meta: dict) -> str:
    """``1e-9 ≤ mass ≤ 1e9 [kg]`` for a field with plausibility bounds."""
    unit = f" [{meta['unit']}]" if meta.get("unit") else ""
    return f"{number_text(meta['minimum'])} ≤ {meta['kind']} ≤ {number_text(meta['maximum'])}{unit}"


def _type_name(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return type(value).__name__


def _bounds_text(meta: dict) -> str:
    if meta.get("kind"):
        return ", " + range_text(meta)
    parts = []
    if meta.get("minimum") is not None:
        parts.append(("> " if meta.get("exclusive_minimum") else ">= ") + repr(meta["minimum"]))
    if meta.get("maximum") is not None:
        parts.append("<= " + repr(meta["maximum"]))
    unit = f" [{meta['unit']}]" if meta.get("unit") else ""
    return (" " + " and ".join(parts) if parts else "") + unit


INT64_LIMIT = 2**63  # an integer parameter is used as an int64


def _too_large(value: Any, integer: bool) -> bool:
    """An integer that no int64 holds (an integer parameter), or no float (a number: 400 digits, say)."""
    if not isinstance(value, int):
        return False
    if integer:
        return not -INT64_LIMIT <= value < INT64_LIMIT
    try:
        float(value)
    except OverflowError:
        return True
    return False


def _check_number(value: Any, key: str, meta: dict, problems: Problems, integer: bool) -> Any:
    kind = "an integer" if integer else "a number"
    ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok:
        problems.add(key, f"expected {kind}{_bounds_text(meta)}, got {_type_name(value)}")
        return None
    if _too_large(value, integer):
        problems.add(key, f"expected {'an integer' if integer else 'a finite number'}{_bounds_text(meta)}, got an "
                          f"integer of {len(str(abs(value)))} digits")
        return None
    number = value if integer else float(value)
    if not integer and number != number or number in (float("inf"), float("-inf")):
        problems.add(key, f"expected a finite number{_bounds_text(meta)}, got {value!r}")
        return None
    low, high = meta.get("minimum"), meta.get("maximum")
    too_low = low is not None and (number <= low if meta.get("exclusive_minimum") else number < low)
    if too_low or (high is not None and number > high):
        expected = range_text(meta) if meta.get("kind") else kind + _bounds_text(meta)
        problems.add(key, f"expected {expected}, got {value!r}")
        return None
    return number


def check_value(annotation: Any, value: Any, key: str, problems: Problems, meta: dict | None = None) -> Any:
    """Check ``value`` against a type annotation; return the converted value or None (problem recorded)."""
    meta = meta or {}
    origin = get_origin(annotation)
    if annotation is float:
        return _check_number(value, key, meta, problems, integer=False)
    if annotation is int:
        return _check_number(value, key, meta, problems, integer=True)
    if annotation is bool:
        if not isinstance(value, bool):
            problems.add(key, f"expected true or false, got {_type_name(value)}")
            return None
        return value
    if annotation is str:
        if not isinstance(value, str) or not value:
            problems.add(key, f"expected a non-empty string, got {_type_name(value)}")
            return None
        return value
    if origin is Literal:
        allowed = get_args(annotation)
        if value not in allowed or isinstance(value, bool) != any(isinstance(a, bool) for a in allowed):
            problems.add(key, f"expected one of {', '.join(repr(a) for a in allowed)}, got {_type_name(value)}")
            return None
        return value
    if origin is tuple:
        (item_type, ellipsis) = get_args(annotation)
        assert ellipsis is Ellipsis, "only homogeneous tuples are supported"
        if not isinstance(value, list):
            problems.add(key, f"expected an array, got {_type_name(value)}")
            return None
        before = len(problems)
        items = tuple(check_value(item_type, item, f"{key}[{i}]", problems, meta) for i, item in enumerate(value))
        return items if len(problems) == before else None
    if origin in (typing.Union, types.UnionType):
        options = [a for a in get_args(annotation) if a is not type(None)]
        if value is None and len(options) < len(get_args(annotation)):
            return None
        if len(options) == 1:
            return check_value(options[0], value, key, problems, meta)
        for option in options:
            trial = Problems()
            converted = check_value(option, value, key, trial, meta)
            if not trial:
                return converted
        problems.add(key, f"expected{' or'.join(_expected(o, meta) for o in options)}, got {_type_name(value)}")
        return None
    raise TypeError(f"unsupported parameter annotation {annotation!r} for {key}")


def read_table(cls: type, table: Any, key: str, problems: Problems, skip: tuple[str, ...] = ()) -> Any:
    """Build ``cls`` (a dataclass) from a TOML table; record problems under ``key`` and return None on any.

    Keys in ``skip`` are left to the caller (nested tables read separately). A dataclass may define
    ``problems(self) -> list[tuple[str, str]]`` for checks across fields; they are recorded under
    ``key.<field>``.
    """
    if not isinstance(table, dict):
        problems.add(key, f"expected a table, got {_type_name(table)}")
        return None
    hints = get_type_hints(cls)
    known = {f.name for f in dataclasses.fields(cls) if f.init}
    before = len(problems)
    values = {}
    for f in dataclasses.fields(cls):
        if not f.init or f.name in skip:
            continue
        if f.name not in table:
            required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
            if required:
                problems.add(f"{key}.{f.name}", f"missing; expected{_expected(hints[f.name], f.metadata)}")
            continue
        converted = check_value(hints[f.name], table[f.name], f"{key}.{f.name}", problems, dict(f.metadata))
        if converted is not None:
            values[f.name] = converted
    for extra in sorted(set(table) - known - set(skip)):
        problems.add(f"{key}.{extra}", f"unknown key; expected one of: {', '.join(sorted(known))}")
    if len(problems) != before:
        return None
    obj = cls(**values)
    if hasattr(obj, "problems"):
        for sub_key, reason in obj.problems():
            problems.add(f"{key}.{sub_key}", reason)
        if len(problems) != before:
            return None
    return obj


def _expected(annotation: Any, meta: Any) -> str:
    if annotation in (float, int):
        return f" a number{_bounds_text(dict(meta))}"
    if get_origin(annotation) is Literal:
        return " one of " + ", ".join(repr(a) for a in get_args(annotation))
    if annotation is str:
        return " a string"
    if get_origin(annotation) is tuple:
        return " an array"
    return " " + getattr(annotation, "__name__", str(annotation))


__all__ = ["Problem", "Problems", "Plausible", "PLAUSIBLE", "quantity", "range_text", "check_value", "read_table",
           "field"]
