"""Any scene file gives a SceneError naming file, key and reason, or a scene that runs (issue 14, item 1).

The bundled scenes are mutated (``tests/manager/scene_mutations.py``: keys deleted, types swapped, extreme and
non-finite numbers, unicode and unsafe names, deep nesting); each mutant must either be refused with a
``SceneError`` whose every problem names a key, or be accepted by ``zencosim check`` (exit status 0, no
exception) and run its first macro-step period in process to a summary that is strict JSON, with subsystem names
that are plain Zenoh key segments. Derandomized: the same examples on every run (``benchmarks/mutate_scenes.py``
counts outcomes over many more).
"""
from __future__ import annotations

import contextlib
import io
import json
import math

import pytest
import zenoh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import zencosim
from tests.manager.scene_mutations import mutated_scene
from zencosim.cli.main import main
from zencosim.manager.scene.checks import name_problem
from zencosim.manager.scene.load import SceneError, load_scene, scene_from_text
from zencosim.manager.scheme.base import SubsystemFailure


def _plain_key_segment(name: str) -> bool:
    """One chunk of a Zenoh key, neither a wildcard nor hidden (``@``), as zenoh itself parses it."""
    try:
        key = str(zenoh.KeyExpr(f"zencosim/run/{name}/y"))
    except zenoh.ZError:
        return False
    return key.split("/") == ["zencosim", "run", name, "y"] and "*" not in name and not name.startswith("@")


@settings(max_examples=100, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.randoms(use_true_random=False))
def test_a_mutated_scene_is_refused_with_its_key_or_runs(tmp_path_factory, rng):
    text, what = mutated_scene(rng)
    path = tmp_path_factory.mktemp("mutant") / "scene.toml"
    path.write_text(text)
    try:
        scene = load_scene(str(path))
    except SceneError as error:
        assert error.problems and all(p.key and p.reason for p in error.problems), what
        assert str(path) in str(error), what
        return
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        status = main(["check", str(path)])
    if status == 2:  # refused when built (the plan, the compensator's design): a SceneError, as a user sees it
        assert str(path) in errors.getvalue(), what
        return
    assert status == 0, what
    assert all(_plain_key_segment(name) for name in scene.subsystems), what
    period = scene.manager.macro_step * math.lcm(*(s.settings.comm_ratio for s in scene.subsystems.values()))
    # the reference is left out: a mutant made absurdly stiff keeps solve_ivp busy up to its evaluation budget
    # (manager.results.reference), seconds that this test need not spend
    short = load_scene(str(path), [f"manager.duration={period!r}", "outputs.reference=none"])
    try:
        summary = zencosim.run(short).summary
    except SubsystemFailure as failure:  # not done: a model whose math module overflows fails the run (exit 1)
        assert "OverflowError" in str(failure), what
        return
    assert summary["steps"] >= 1, what
    json.dumps(summary, allow_nan=False)  # strict JSON: non-finite values are null (summary["non_finite"])


@pytest.mark.parametrize("override, key, reason", [
    ("description=true", "description", "expected a string"),
    ("manager.duration=1e308", "manager.duration", "at most"),
    ("manager.macro_step=1e-15", "manager.macro_step", "at least 1 ns"),
    ("manager.duration=1e-4", "manager.duration", "at least one macro-step period"),
    ("manager.duration=1e7", "manager.duration", "shorten manager.duration or lengthen manager.macro_step"),
    ("subsystems.S1.micro_step=nan", "subsystems.S1.micro_step", "finite"),
    ("manager.timeout=1e308", "manager.timeout", "at most 9.223e+09 s"),
])
def test_the_issues_overrides_are_refused_naming_the_key(override, key, reason):
    """The findings of issue 14 (a traceback or an accepted scene that cannot run), now scene errors."""
    from zencosim.manager.assembly import plan_scene  # the memory estimate is made with the plan
    with pytest.raises(SceneError) as caught:
        plan_scene(load_scene("two_mass_undamped", [override]))
    assert [p.key for p in caught.value.problems] == [key]
    assert reason in caught.value.problems[0].reason


@pytest.mark.parametrize("name", ["S*", "a/b", "**", "@x", "", "x?", "x#", "$x", "a b", "a.b", "\x1b[31m"])
def test_a_subsystem_name_that_is_no_plain_key_segment_is_refused(name):
    text = load_scene_text("two_mass_undamped").replace("[subsystems.S2]", f"[subsystems.{json.dumps(name)}]")
    text = text.replace('motion_side = "S2.m2"', f"motion_side = {json.dumps(name + '.m2')}")
    with pytest.raises(SceneError) as caught:
        scene_from_text(text, "renamed.toml")
    assert f"subsystems.{name}" in [p.key for p in caught.value.problems]


@pytest.mark.parametrize("name", ["S1", "motor_2", "left-arm", "é", "名前"])
def test_names_that_are_plain_key_segments_are_accepted(name):
    """The scene's rule (letters, digits, '_', '-') admits only names zenoh parses as one plain chunk."""
    assert name_problem(name) is None and _plain_key_segment(name)


def test_deep_nesting_is_a_scene_error_not_a_recursion_error():
    text = load_scene_text("two_mass_undamped").replace('signals = ["x2", "fc"]', "signals = " + "[" * 5000 + "]" * 5000)
    with pytest.raises(SceneError, match="nested too deeply"):
        scene_from_text(text, "deep.toml")
    with pytest.raises(SceneError, match="nested too deeply"):
        load_scene("two_mass_undamped", ["outputs.signals=" + "[" * 20 + "]" * 20])


def load_scene_text(name: str) -> str:
    from importlib import resources
    return (resources.files("zencosim.scenes") / f"{name}.toml").read_text()


@pytest.mark.parametrize("point, role", [("S2.points.m2", "position"), ("S1.points.m1", "position_input"),
                                         ("S1.points.m1", "force"), ("S2.points.m2", "velocity")])
def test_an_empty_list_of_a_points_variables_is_one_line_and_exit_2(point, role):
    """``position = []`` on a Python model's point: one problem naming the key."""
    from tests.conftest import REPO
    scene = str(REPO / "zencosim" / "examples" / "scenes" / "two_mass_damped_python.toml")
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
        status = main(["check", scene, "--set", f"subsystems.{point}.{role}=[]"])
    assert status == 2 and "Traceback" not in errors.getvalue(), errors.getvalue()
    assert (f"subsystems.{point}.{role}: expected a variable name, or a list of one per component, got an empty list"
            in " ".join(errors.getvalue().split()))


TIME_KEYS = ("manager.macro_step", "manager.duration", "subsystems.S1.micro_step",
             "manager.energy_control.max_step_size", "manager.energy_control.step_size")


@settings(max_examples=30, deadline=None)
@given(key=st.sampled_from(TIME_KEYS), seconds=st.floats() | st.sampled_from([1e300, 1e308, 5e-324, 9.3e9, 2.0**63]))
def test_any_float_as_a_time_loads_or_is_refused_by_its_key(key, seconds):
    """Every time of a TOML scene goes through one conversion to nanoseconds (manager.scene.times): any float gives
    a scene, or problems that each name a key, among them this one when the float is no time (not finite, under
    1 ns, beyond 2**63 - 1 ns)."""
    overrides = {"manager.step_control": "energy", "manager.energy_control.max_step_size": 0.01, key: seconds}
    try:
        scene = zencosim.load_scene("two_mass_undamped", overrides)
    except SceneError as error:
        assert all(p.key and p.reason for p in error.problems)
        if not (math.isfinite(seconds) and 1e-9 <= seconds <= (2**63 - 1) * 1e-9):
            assert key in {p.key for p in error.problems}, error
    else:
        assert scene.manager.macro_step_ns >= 1 and scene.manager.duration_ns <= 2**63 - 1
