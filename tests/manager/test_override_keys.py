"""``--set`` keys: dotted parts, and a part in double quotes that holds dots (an FMU variable such as crane-fmu's
``boom.end[0]``), as TOML writes such keys."""
from __future__ import annotations

import pytest

from zencosim.manager.scene.overrides import apply_overrides, parse_override
from zencosim.subsystems.params import Problems


@pytest.mark.parametrize("text,path,value", [
    ("manager.macro_step=0.004", ["manager", "macro_step"], 0.004),
    ("subsystems.osc.units.f[3]=N.m", ["subsystems", "osc", "units", "f[3]"], "N.m"),
    ('subsystems.crane.units."boom.end[0]"=m', ["subsystems", "crane", "units", "boom.end[0]"], "m"),
    ('a.b = "x=y"', ["a", "b"], "x=y"),
])
def test_a_key_splits_at_dots_outside_quotes(text, path, value):
    assert parse_override(text) == (path, value)


@pytest.mark.parametrize("text", ["a..b=1", "=3", "abc", 'a."b=1'])
def test_a_malformed_key_is_refused(text):
    with pytest.raises(ValueError, match="expected key=value"):
        parse_override(text)


def test_a_quoted_part_sets_one_key():
    problems = Problems()
    document = apply_overrides({"subsystems": {"crane": {}}}, ['subsystems.crane.units."boom.end[0]"=m'], problems)
    assert not problems and document["subsystems"]["crane"]["units"] == {"boom.end[0]": "m"}
