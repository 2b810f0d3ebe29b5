"""``--set key=value`` overrides of a scene's TOML document."""
from __future__ import annotations

import copy
import re
import tomllib
from typing import Any, Sequence

import tomli_w

from zencosim.subsystems.params import Problems


def toml_value(value: object) -> str:
    """``value`` written as TOML for ``key=value`` (floats exactly: they are read back bit for bit)."""
    return tomli_w.dumps({"v": value}).partition("=")[2].strip()


_KEY_PART = r'(?:"[^"]*"|[^."=]+)'  # a bare key part, or a quoted one, which may hold dots: "fixation.end[0]"
_KEY = re.compile(rf"\s*({_KEY_PART}(?:\.{_KEY_PART})*)\s*=")


def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``a.b.c=value`` into a key path and a TOML value (a bare word is taken as a string); a part of the
    key in double quotes is one part, dots included (``subsystems.crane.units."boom.end[0]"=m``)."""
    match = _KEY.match(text)
    parts = [part.strip() for part in re.findall(_KEY_PART, match.group(1))] if match else []
    if not parts or not all(parts):
        raise ValueError(f"--set {text!r}: expected key=value, e.g. manager.macro_step=0.004")
    path = [part[1:-1] if part.startswith('"') else part for part in parts]
    raw = text[match.end():]
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    except RecursionError:  # tomllib parses nested arrays recursively
        raise ValueError(f"--set {text[:40]!r}...: arrays nested too deeply") from None
    return path, value


def apply_overrides(document: dict, overrides: Sequence[str], problems: Problems) -> dict:
    """Return a copy of ``document`` with each ``key=value`` set; tables cannot be overwritten by scalars, and a
    table given inline (``key={ a = 1 }``) replaces the key's whole table."""
    result = copy.deepcopy(document)
    for text in overrides:
        try:
            path, value = parse_override(text)
        except ValueError as error:
            problems.add("--set", str(error))
            continue
        node = result
        for depth, part in enumerate(path[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                problems.add(".".join(path[:depth + 1]), f"--set {text}: is a value, not a table")
                break
            node = child
        else:
            if isinstance(node.get(path[-1]), dict) and not isinstance(value, dict):
                problems.add(".".join(path), f"--set {text}: is a table; only scalars can be overridden, or the "
                                             "whole table given inline ({ key = value, … })")
            else:
                node[path[-1]] = value
    return result
