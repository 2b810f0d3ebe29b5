"""Effects: the force laws a scene can name. A subsystem is the sum of the effects its scene names.

Each effect is one class in its own module: its parameters as dataclass fields (with units), its
``kind`` and the number of points it connects. ``EFFECTS`` maps the names scenes use to classes.

Kinds:

* ``linear`` — a two-point element that also stamps itself into stiffness/damping matrices (the
  fast path of the point-mass model);
* ``nonlinear`` — a two-point element evaluated from its force law at every evaluation;
* ``external`` — a force of time on one body.

Every two-point element (linear or nonlinear) has a scalar force law ``force(η, η̇)`` and a stored
energy ``potential(η)``: the force on point a along the element, for the elongation η and its rate.
On a line ``η = x_a − x_b`` (signed; ``free_length`` is 0); in the plane ``η = |r_a − r_b| − l0``,
``η̇ = e · (v_a − v_b)`` with the unit vector ``e = (r_a − r_b)/|r_a − r_b|``, and the force on a is
``force(η, η̇) e``. Point b receives the opposite force.
"""
from dataclasses import dataclass

from zencosim.subsystems.effects.chirp_force import ChirpForce
from zencosim.subsystems.effects.damper import Damper
from zencosim.subsystems.effects.quadratic_damper import QuadraticDamper
from zencosim.subsystems.effects.spring import Spring
from zencosim.subsystems.effects.sqrt_spring import SqrtSpring
from zencosim.subsystems.params import Problems, read_table

EFFECTS: dict[str, type] = {
    "spring": Spring,
    "damper": Damper,
    "sqrt_spring": SqrtSpring,
    "quadratic_damper": QuadraticDamper,
    "chirp_force": ChirpForce,
}


@dataclass(frozen=True)
class PlacedEffect:
    """An effect of the scene and the points it connects (body or terminal names; None is the ground)."""

    name: str
    effect: object
    endpoints: tuple[str | None, ...]


def read_effect(table: object, key: str, problems: Problems) -> object | None:
    """Read one effect table (``type`` plus the parameters of that effect class)."""
    if not isinstance(table, dict):
        problems.add(key, "expected a table with a 'type' key")
        return None
    kind = table.get("type")
    if not isinstance(kind, str) or kind not in EFFECTS:
        problems.add(f"{key}.type", f"expected one of {', '.join(sorted(EFFECTS))}, got {kind!r}")
        return None
    params = {k: v for k, v in table.items() if k not in ("type", "bodies")}
    return read_table(EFFECTS[kind], params, key, problems)


__all__ = ["EFFECTS", "PlacedEffect", "read_effect", "Spring", "Damper", "SqrtSpring", "QuadraticDamper", "ChirpForce"]
