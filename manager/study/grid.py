"""The grid of a study: the scene settings it varies, the points they span, and what each point adds to be
a scene that runs.

A point is a set of scene overrides (``--set`` keys). The macro-step is the axis every plot and answer is
read along; the point's other varied keys (extrapolation, compensation, energy correction, implicit
method, …) make up its *method*. Two settings follow the macro-step unless the grid sets them:

* a subsystem that integrates with one micro-step per communication step (papers 000 §5.1 and 002 §3.3:
  ``micro_step`` = macro-step × ``comm_ratio``) keeps doing so;
* a duration that is not a whole number of schedule periods (macro-step × lcm of the ratios) is
  shortened to the largest one that is.

Both are added to the point's overrides, so the cache and the report see them.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

from zencosim.manager.scene.checks import check_compensation
from zencosim.manager.scene.load import Scene, SceneError, load_scene
from zencosim.manager.scene.overrides import parse_override, toml_value
from zencosim.manager.scene.times import NotATime, nanoseconds
from zencosim.subsystems.params import Problems

MACRO_STEP = "manager.macro_step"
DEFAULT_STEP_FACTORS = (0.5, 1.0, 2.0, 4.0)  # default macro-steps: the scene's own times these


class GridError(ValueError):
    """A ``--vary`` option that cannot be read, or a grid without a macro-step to vary."""


@dataclass(frozen=True)
class Axis:
    """One varied key and its values (as TOML reads them)."""

    key: str
    values: tuple


@dataclass(frozen=True)
class Point:
    """One point of the grid: its varied values, and the overrides it runs with (varied and derived)."""

    values: dict  # varied key -> value
    overrides: tuple[str, ...]  # base --set options, the varied values, then the derived settings
    derived: tuple[str, ...]  # the settings that followed the macro-step
    key: str = ""  # the first 16 hex digits of the digest of the scene it runs (manager.study.cache)

    @property
    def macro_step(self) -> float:
        return self.values[MACRO_STEP]

    @property
    def method(self) -> str:
        """The varied values other than the macro-step, ``key=value`` without the ``manager.`` prefix."""
        return method_label({k: v for k, v in self.values.items() if k != MACRO_STEP})


def method_label(values: dict) -> str:
    """``key=value, …`` of ``values`` (keys without ``manager.``); "as the scene" for none."""
    return ", ".join(f"{key.removeprefix('manager.')}={display(v)}" for key, v in values.items()) or "as the scene"


def display(value: object) -> str:
    """A value as a person reads it: strings bare, booleans in lower case, numbers as TOML writes them."""
    return value if isinstance(value, str) else toml_value(value)


def parse_axis(text: str) -> Axis:
    """``key=v1,v2,...`` as ``--vary`` takes it (each value read as ``--set`` reads one)."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip() or not raw.strip():
        raise GridError(f"--vary {text!r}: expected key=value,value,..., e.g. manager.macro_step=0.5e-3,1e-3")
    values = tuple(parse_override(f"{key.strip()}={item}")[1] for item in raw.split(","))
    if len(set(map(toml_value, values))) != len(values):
        raise GridError(f"--vary {text!r}: a value is given twice")
    return Axis(key.strip(), values)


def merge_axes(axes: list[Axis]) -> list[Axis]:
    """The axes of ``--vary`` options, the macro-step first: each key once, the macro-step among them."""
    keys = [a.key for a in axes]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise GridError(f"--vary {', '.join(twice)}: given more than once; give every value in one --vary")
    if MACRO_STEP not in keys:
        raise GridError(f"the grid must vary {MACRO_STEP}: it is the axis of every plot and answer")
    return sorted(axes, key=lambda a: a.key != MACRO_STEP)


def default_axes(scene: Scene) -> list[Axis]:
    """The grid a study of ``scene`` runs when the user gives none (docs/study.md): the scene's macro-step
    times 0.5, 1, 2 and 4; extrapolation orders 0, 1, 2; for the explicit scheme energy correction off and
    on, paper 000's compensator where the scene's structure admits one, and Jacobi and Gauss–Seidel coupling
    (Gauss–Seidel's points with correction or the compensator are skipped: refused);
    for the implicit scheme the three coupling methods of paper 003."""
    h = scene.manager.macro_step
    axes = [Axis(MACRO_STEP, tuple(_whole_ns(h * f) for f in DEFAULT_STEP_FACTORS)),
            Axis("manager.extrapolation", (0, 1, 2))]
    if scene.manager.scheme == "implicit":
        return axes + [Axis("manager.implicit.method", ("baumgarte", "weighted-multiplier", "projection"))]
    problems = Problems()
    check_compensation(replace(scene.manager, correction=None), scene.couplings, scene.subsystems, problems)
    if not problems:
        axes.append(Axis("manager.compensation", ("none", "eigenstructure")))
    axes.append(Axis("manager.scheme", ("jacobi", "gauss-seidel")))
    return axes + [Axis("manager.correction.enabled", (False, True))]


def _whole_ns(seconds: float) -> float:
    return round(seconds * 1e9) * 1e-9


def expand(scene: Scene, axes: list[Axis]) -> tuple[list[Point], list[tuple[dict, str]]]:
    """Every combination of the axes' values as a point of ``scene`` (loaded with its own overrides): the points
    that load, and the ones that do not with the first reason (a compensator with energy correction, …)."""
    points, skipped = [], []
    for combination in itertools.product(*(a.values for a in axes)):
        values = dict(zip((a.key for a in axes), combination))
        derived = derived_overrides(scene, values)
        point = Point(values, tuple(scene.overrides) + as_overrides(values) + derived, derived)
        try:
            loaded = load_scene(scene.path, list(point.overrides))
        except SceneError as error:
            skipped.append((values, str(error.problems[0])))
            continue
        points.append(replace(point, key=loaded.digest[:16]))
    return points, skipped


def as_overrides(values: dict) -> tuple[str, ...]:
    """``key=value`` options of ``values``."""
    return tuple(f"{k}={toml_value(v)}" for k, v in values.items())


def derived_overrides(scene: Scene, values: dict) -> tuple[str, ...]:
    """The micro-steps and the duration that follow the point's macro-step (module docstring); none when the
    macro-step or the duration is no time (the point's scene is refused for it, by key)."""
    try:
        h_ns = nanoseconds(values[MACRO_STEP])
        duration_ns = nanoseconds(values.get("manager.duration", scene.manager.duration), whole=False)
    except NotATime:
        return ()
    derived = []
    ratios = []
    for name, sub in scene.subsystems.items():
        ratio = values.get(f"subsystems.{name}.comm_ratio", sub.settings.comm_ratio)
        ratios.append(ratio)
        key = f"subsystems.{name}.micro_step"
        if key not in values and sub.settings.micro_step_ns == scene.comm_step_ns(name) and h_ns * ratio != sub.settings.micro_step_ns:
            derived.append(f"{key}={toml_value(h_ns * ratio * 1e-9)}")
    period = h_ns * math.lcm(*ratios)
    if "manager.duration" not in values and duration_ns % period:
        derived.append(f"manager.duration={toml_value(duration_ns // period * period * 1e-9)}")
    return tuple(derived)
