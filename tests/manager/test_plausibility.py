"""Plausibility bounds of the built-in models' and effects' parameters (issue 25, item 1; docs/scenes.md).

Values no physical system has (a zero link mass, a negative compressibility, a density of 1e308, an inertia
of 1e-15, a length of 5e-324, positions and velocities of ±2^63, a stiffness of 1e308 or a mass of 5e-324, the
last two a ``LinAlgError`` traceback when the run started) passed ``zencosim check``; each is now a scene error
naming the file, the key and the bound (exit status 2). Every bundled scene stays within the bounds, every
float parameter has them, and the documented table is the declared one.
"""
from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import tomllib
import typing

import pytest

from tests.conftest import REPO
from zencosim.manager.scene.load import SceneError, bundled_scene_names, load_scene
from zencosim.subsystems.effects import EFFECTS
from zencosim.subsystems.models.crane_arm import CraneArmSpec
from zencosim.subsystems.models.hydraulic_cylinder import HydraulicCylinderSpec, SpoolLaw
from zencosim.subsystems.models.masses import Body
from zencosim.subsystems.models.pendulum import PendulumSpec
from zencosim.subsystems.models.planar_link import LinkSpec
from zencosim.subsystems.params import PLAUSIBLE, Problems, quantity, range_text, read_table

# every dataclass whose fields a scene's model or effect table holds
PARAMETER_CLASSES = (Body, PendulumSpec, LinkSpec, CraneArmSpec, HydraulicCylinderSpec, SpoolLaw, *EFFECTS.values())

ISSUE_VALUES = [  # scene, override, key, the bound's text
    ("hydraulic_crane", "subsystems.M.link1_mass=0.0", "subsystems.M.link1_mass", "1e-9 ≤ mass ≤ 1e9 [kg]"),
    ("hydraulic_crane", "subsystems.M.mass_q=0.0", "subsystems.M.mass_q", "1e-9 ≤ mass ≤ 1e9 [kg]"),
    ("hydraulic_crane", "subsystems.H.compressibility_a=-6.53e-10", "subsystems.H.compressibility_a",
     "1e-12 ≤ compressibility ≤ 1e-4 [1/Pa]"),
    ("hydraulic_crane", "subsystems.H.density=1e308", "subsystems.H.density", "1e-3 ≤ density ≤ 3e4 [kg/m^3]"),
    ("double_pendulum", "subsystems.L1.inertia=1e-15", "subsystems.L1.inertia", "1e-12 ≤ inertia ≤ 1e15 [kg m^2]"),
    ("double_pendulum", "subsystems.L2.length=5e-324", "subsystems.L2.length", "1e-6 ≤ length ≤ 1e6 [m]"),
    ("two_mass_damped", f"subsystems.S1.bodies.m1.x0={2**63}", "subsystems.S1.bodies.m1.x0",
     "-1e6 ≤ position ≤ 1e6 [m]"),
    ("two_mass_damped", f"subsystems.S1.bodies.m1.x0={-2**63}", "subsystems.S1.bodies.m1.x0",
     "-1e6 ≤ position ≤ 1e6 [m]"),
    ("two_mass_damped", f"subsystems.S2.bodies.m2.v0={2**63}", "subsystems.S2.bodies.m2.v0",
     "-1e5 ≤ velocity ≤ 1e5 [m/s]"),
    ("two_mass_damped", f"subsystems.S2.bodies.m2.v0={-2**63}", "subsystems.S2.bodies.m2.v0",
     "-1e5 ≤ velocity ≤ 1e5 [m/s]"),
    ("double_pendulum", f"subsystems.L1.angular_velocity0={-2**63}", "subsystems.L1.angular_velocity0",
     "-1e5 ≤ angular velocity ≤ 1e5 [rad/s]"),
    ("coupled_pendula", f"subsystems.M1.pivot=[{2**63}, 0.0]", "subsystems.M1.pivot[0]", "-1e6 ≤ position ≤ 1e6 [m]"),
    ("two_mass_undamped", "couplings.c.effects.kc.stiffness=1e308", "couplings.c.effects.kc.stiffness",
     "0 ≤ stiffness ≤ 1e12 [N/m]"),
    ("two_mass_undamped", "subsystems.S1.bodies.m1.mass=5e-324", "subsystems.S1.bodies.m1.mass",
     "1e-9 ≤ mass ≤ 1e9 [kg]"),
]


@pytest.mark.parametrize("scene, override, key, bound", ISSUE_VALUES, ids=[v[1].split("=")[0] for v in ISSUE_VALUES])
def test_the_issues_values_are_refused_naming_key_and_bound(scene, override, key, bound):
    with pytest.raises(SceneError) as caught:
        load_scene(scene, [override])
    reasons = {p.key: p.reason for p in caught.value.problems}
    assert key in reasons, reasons
    given = tomllib.loads("v = " + override.split("=", 1)[1])["v"]
    assert reasons[key] == f"expected {bound}, got {given[0] if isinstance(given, list) else given!r}", reasons[key]


def test_check_refuses_them_with_one_line_each_and_exit_status_2():
    """As a user sees it: ``zencosim check`` exits 2 with the file, the key and the bound, no traceback."""
    overrides = ["subsystems.M.link1_mass=0.0", "subsystems.H.compressibility_a=-6.53e-10",
                 "subsystems.H.density=1e308"]
    result = subprocess.run([sys.executable, "-m", "zencosim", "check", "hydraulic_crane",
                             *(a for o in overrides for a in ("--set", o))],
                            capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    scene = str(REPO / "scenes" / "hydraulic_crane.toml")
    for line in (f"{scene}: subsystems.M.link1_mass: expected 1e-9 ≤ mass ≤ 1e9 [kg], got 0.0",
                 f"{scene}: subsystems.H.compressibility_a: expected 1e-12 ≤ compressibility ≤ 1e-4 [1/Pa], got "
                 "-6.53e-10",
                 f"{scene}: subsystems.H.density: expected 1e-3 ≤ density ≤ 3e4 [kg/m^3], got 1e+308"):
        assert line in result.stderr, result.stderr


@pytest.mark.parametrize("name", bundled_scene_names())
def test_every_bundled_scene_is_within_the_bounds(name):
    load_scene(name)


def _float_fields(cls) -> list[dataclasses.Field]:
    hints = typing.get_type_hints(cls)
    numeric = (float, tuple[float, ...], float | None)
    return [f for f in dataclasses.fields(cls) if f.init and hints[f.name] in numeric]


@pytest.mark.parametrize("cls", PARAMETER_CLASSES, ids=lambda c: c.__name__)
def test_every_number_a_scene_gives_a_model_or_an_effect_is_bounded_on_both_sides(cls):
    fields = _float_fields(cls)
    assert fields, cls
    for f in fields:
        assert f.metadata.get("minimum") is not None and f.metadata.get("maximum") is not None, (cls, f.name)
        assert f.metadata.get("kind") in PLAUSIBLE or (f.metadata["minimum"], f.metadata["maximum"]) == (0.0, 1.0), \
            (cls, f.name)  # a plausibility kind, or a fraction (the spool's amplitude)


def test_every_bound_keeps_the_models_products_finite_and_their_divisors_normal():
    """The numerical half of the rationale: products of two bounded factors (k x, c v, m v^2, k x^2 / m) stay
    far below float64's largest number, and no lower bound of a divisor is zero or subnormal."""
    largest = max(max(abs(b.minimum), abs(b.maximum)) for b in PLAUSIBLE.values())
    assert largest ** 2 < 1e40 < sys.float_info.max
    for kind in ("mass", "inertia", "length", "area", "density", "compressibility", "sweep time",
                 "discharge coefficient"):
        assert PLAUSIBLE[kind].minimum >= sys.float_info.min * 1e200, kind


def test_the_bound_is_inclusive_and_the_message_states_it():
    problems = Problems()
    assert read_table(Body, {"mass": 1e-9, "x0": -1e6, "v0": 1e5}, "b", problems) == Body(1e-9, -1e6, 1e5)
    assert not problems
    assert read_table(Body, {"mass": "heavy"}, "b", problems) is None
    assert [str(p) for p in problems] == ["b.mass: expected a number, 1e-9 ≤ mass ≤ 1e9 [kg], got the string 'heavy'"]
    assert range_text(quantity("Pa", kind="pressure")) == "0 ≤ pressure ≤ 1e9 [Pa]"


def test_docs_table_is_the_declared_bounds():
    text = (REPO / "docs" / "scenes.md").read_text()
    section = text.split("## Plausibility bounds", 1)[1].split("\n## ", 1)[0]
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| ([a-z ]+) \| `([^`]+)` \|", section, re.M)}
    assert rows == {kind: range_text(quantity(b.unit, kind=kind)) for kind, b in PLAUSIBLE.items()}


@pytest.mark.parametrize("overrides", [
    # the stiffest coupling on the lightest mass, started at the largest position and velocity
    ["subsystems.S1.bodies.m1.mass=1e-9", "couplings.c.effects.kc.stiffness=1e12", "subsystems.S1.bodies.m1.x0=1e6",
     "subsystems.S1.bodies.m1.v0=1e5"],
    # the heaviest mass beside the lightest, the strongest damper between them
    ["subsystems.S1.bodies.m1.mass=1e-9", "subsystems.S2.bodies.m2.mass=1e9", "couplings.c.effects.cc.damping=1e12"],
])
def test_a_scene_at_the_bounds_runs_or_reports_its_divergence_without_a_traceback(overrides):
    """Within the bounds nothing overflows into a traceback: the run completes (0) or says it diverged (3)."""
    result = subprocess.run([sys.executable, "-m", "zencosim", "run", "two_mass_damped",
                             "--set", "manager.duration=0.01", *(a for o in overrides for a in ("--set", o))],
                            capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode in (0, 3) and "Traceback" not in result.stderr, result.stderr
