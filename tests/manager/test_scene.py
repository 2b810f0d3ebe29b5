"""Scene loading: bundled scenes are valid, overrides work, and every problem is reported with the
file, the dotted key and what was expected."""
from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import REPO
from zencosim.manager.assembly import build_subsystems
from zencosim.manager.plan.run_plan import compile_plan
from zencosim.manager.scene.load import SceneError, bundled_scene_names, load_scene

BUNDLED = bundled_scene_names()


def test_the_papers_benchmarks_are_bundled():
    assert {"two_mass_undamped", "two_mass_damped", "two_mass_chirp", "four_mass", "double_oscillator",
            "multiple_oscillator_n3", "multiple_oscillator_n5"} <= set(BUNDLED)


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_scene_is_valid(name):
    scene = load_scene(name)
    subsystems = build_subsystems(scene)
    compile_plan(scene, {n: (s.inputs, s.outputs, s.effects) for n, s in subsystems.items()})


def test_paper_000_two_mass_parameters():
    scene = load_scene("two_mass_damped")
    s1, s2 = scene.subsystems["S1"].spec, scene.subsystems["S2"].spec
    assert (s1.bodies["m1"].mass, s2.bodies["m2"].mass) == (1.0, 1.0)
    assert (s1.bodies["m1"].v0, s2.bodies["m2"].v0) == (100.0, -100.0)
    stiffness = {e.name: e.effect.stiffness for s in (s1, s2) for e in s.effects if hasattr(e.effect, "stiffness")}
    assert stiffness == {"k1": 10.0, "k2": 1000.0}
    assert scene.manager.macro_step == 0.001 and scene.manager.duration == 10.0


def test_override_changes_a_scalar_and_the_digest():
    base = load_scene("two_mass_damped")
    changed = load_scene("two_mass_damped", ["manager.macro_step=0.004", "subsystems.S1.micro_step=0.004",
                                             "subsystems.S2.micro_step=0.004"])
    assert changed.manager.macro_step_ns == 4_000_000
    assert changed.digest != base.digest
    assert load_scene("two_mass_damped").digest == base.digest


def test_an_inline_table_replaces_a_whole_table():
    """``--set key={…}`` (the only way to give an empty table, ``feedthrough = {}``) replaces the table: the body's
    keys it does not give take their defaults, x0 = v0 = 0."""
    scene = load_scene("two_mass_damped", ["subsystems.S1.bodies.m1={ mass = 2.0 }"])
    assert scene.resolved["subsystems"]["S1"]["bodies"]["m1"] == {"mass": 2.0}
    body = scene.subsystems["S1"].spec.bodies["m1"]
    assert (body.mass, body.x0, body.v0) == (2.0, 0.0, 0.0)


def test_zero_coefficient_builds_no_effect():
    undamped = build_subsystems(load_scene("two_mass_undamped"))
    assert undamped["S1"].effects == ("k1", "c.kc")
    damped = build_subsystems(load_scene("two_mass_undamped", ["subsystems.S1.effects.c1.damping=0.1"]))
    assert damped["S1"].effects == ("k1", "c1", "c.kc")


def _problems(name, overrides):
    with pytest.raises(SceneError) as caught:
        load_scene(name, overrides)
    return caught.value, {p.key: p.reason for p in caught.value.problems}


def test_every_problem_is_reported_at_once_with_its_key():
    error, problems = _problems("two_mass_damped", ["manager.macro_stp=0.004", "subsystems.S1.bodies.m1.mass=-1",
                                                    "couplings.c.motion_side=S3.m2", "manager.extrapolation=3"])
    assert "two_mass_damped.toml" in str(error)
    assert "unknown key" in problems["manager.macro_stp"]
    assert "1e-9 ≤ mass ≤ 1e9 [kg]" in problems["subsystems.S1.bodies.m1.mass"]
    assert "unknown subsystem 'S3'" in problems["couplings.c.motion_side"]
    assert "<= 2" in problems["manager.extrapolation"]


@pytest.mark.parametrize("override,key,reason", [
    ("subsystems.S1.micro_step=0.0003", "subsystems.S1.micro_step", "divisor of the communication step"),
    ("manager.macro_step=0.003", "manager.duration", "multiple of 0.003 s"),
    ("manager.duration=abc", "manager.duration", "expected a number"),
    ("subsystems.S1.integrator=euler", "subsystems.S1.integrator", "symplectic_euler"),
    ("subsystems.S1.effects.k1.type=gear", "subsystems.S1.effects.k1.type", "expected one of"),
    ("subsystems.S1.bodies=1", "subsystems.S1.bodies", "only scalars"),
    ("couplings.c.force=x2", "couplings.c.force", "signal names must differ"),
    ("outputs.signals=['x9']", "outputs.signals[0]", "unknown signal 'x9'"),
    ("subsystems.S1.effects.k1.bodies=['m9']", "subsystems.S1.effects.k1.bodies", "unknown body 'm9'"),
])
def test_bad_values_are_named(override, key, reason):
    _, problems = _problems("two_mass_damped", [override])
    assert key in problems, problems
    assert reason in problems[key]


def test_a_missing_file_and_invalid_toml_are_reported(tmp_path):
    with pytest.raises(SceneError, match="no bundled scene of that name"):
        load_scene("no_such_scene")
    broken = tmp_path / "broken.toml"
    broken.write_text("name = 'x'\n[manager\n")
    with pytest.raises(SceneError, match="broken.toml.*not valid TOML"):
        load_scene(str(broken))


def test_cli_exits_2_naming_file_key_and_reason():
    result = subprocess.run([sys.executable, "-m", "zencosim", "check", "two_mass_damped",
                             "--set", "subsystems.S2.bodies.m2.mass=0"], capture_output=True, text=True, cwd=REPO)
    assert result.returncode == 2
    assert "two_mass_damped.toml: subsystems.S2.bodies.m2.mass: expected 1e-9 ≤ mass ≤ 1e9 [kg], got 0" in result.stderr
