"""The public Python API (docs/api.md): its example runs as written, its names resolve, and overrides given as
a dict reach the scene exactly."""
from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zencosim
from tests.conftest import REPO


def _python_blocks(markdown: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", markdown, flags=re.S | re.M)


@pytest.mark.multiprocess
@pytest.mark.timeout(300)
def test_the_example_of_docs_api_runs(tmp_path, monkeypatch, capsys):
    (example,) = _python_blocks((REPO / "docs" / "api.md").read_text())
    monkeypatch.chdir(tmp_path)
    exec(compile(example, str(REPO / "docs" / "api.md"), "exec"), {})  # its last line asserts bit-identical buses
    printed = capsys.readouterr().out
    assert printed.count("True") + printed.count("False") == 6  # one line per point of the sweep
    assert (tmp_path / "sweep_last_point.csv").read_text().startswith("time [s],")


def test_every_public_name_resolves():
    for name in zencosim.__all__:
        assert getattr(zencosim, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'runn'"):
        zencosim.runn


@settings(max_examples=60, deadline=None)
@given(st.floats(-1e6, 1e6))  # any float within the position bound (docs/scenes.md, plausibility bounds)
def test_a_float_override_given_in_a_dict_reaches_the_scene_bit_for_bit(value):
    scene = zencosim.load_scene("two_mass_damped", {"subsystems.S1.bodies.m1.x0": value})
    assert scene.resolved["subsystems"]["S1"]["bodies"]["m1"]["x0"].hex() == value.hex()
    assert scene.digest == zencosim.load_scene("two_mass_damped", [f"subsystems.S1.bodies.m1.x0={value!r}"]).digest


def test_dict_overrides_of_every_toml_type_equal_their_set_strings():
    as_dict = zencosim.load_scene("two_mass_damped", {"manager.extrapolation": 1, "manager.correction.enabled": True,
                                                      "description": "a sweep point", "manager.macro_step": 0.002})
    as_strings = zencosim.load_scene("two_mass_damped", ["manager.extrapolation=1", "manager.correction.enabled=true",
                                                         "description='a sweep point'", "manager.macro_step=0.002"])
    assert as_dict.digest == as_strings.digest


def test_a_run_of_one_macro_step_has_a_summary():
    result = zencosim.run(zencosim.load_scene("two_mass_damped", {"manager.duration": 0.001}))
    assert result.summary["steps"] == 1 and result.summary["stable"]
    assert result.summary["energy"]["growth_rate_per_s"] == 0.0  # too short to show growth


def test_a_bad_scene_raises_scene_error_naming_the_key():
    with pytest.raises(zencosim.SceneError, match="manager.macro_step"):
        zencosim.load_scene("two_mass_damped", {"manager.macro_step": -1.0})
    with pytest.raises(ValueError, match="unknown bus 'mqtt'; expected one of inproc, zenoh"):
        zencosim.run("two_mass_damped", bus="mqtt")
