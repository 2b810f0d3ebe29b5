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


def quantity(unit: str, minimum: float | None = None, maximum: float | None = None,
             exclusive_minimum: bool = False) -> dict:
    """Field metadata for a physical quantity: its SI unit and optional bounds."""
    return {"unit": unit, "minimum": minimum, "maximum": maximum, "exclusive_minimum": exclusive_minimum}


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
        problems.add(key, f"expected {kind}{_bounds_text(meta)}, got {value!r}")
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


__all__ = ["Problem", "Problems", "quantity", "check_value", "read_table", "field"]
