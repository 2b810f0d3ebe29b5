"""Scenes of any size: a chain and a star of point masses, one mass per subsystem, as TOML text.

``mass_chain(n)``: masses 1..n in a line; coupling ``c<i>`` joins subsystem ``S<i>`` (force side: the
coupling spring–damper is in it) to ``S<i+1>`` (motion side), so every inner subsystem is the motion side of
one coupling and the force side of the next. Its force output feeds through from the next mass's motion,
a state: no algebraic loop, whatever n (docs/scenes.md, "Topologies").
``mass_star(n)``: a hub mass ``H`` (motion side of every coupling) and n − 1 leaves ``S<i>``, each the force side
of its coupling to the hub; the couplings share the hub's motion signals (as paper 002's multiple oscillator).

Every mass has 1 kg, a spring of 100 N/m and a damper of 0.1 N s/m to ground; coupling elements 100 N/m and
0.1 N s/m; the first mass starts at 0.1 m, the others at rest; 1 ms macro-steps, symplectic Euler, ZOH,
checked against the analytic solution. The bundled scene ``mass_chain`` is ``mass_chain(5)``; larger ones
are written with ``python -m zencosim.scenes.topologies chain 17 > chain17.toml`` or from Python.
"""
from __future__ import annotations

import sys

MASS, GROUND_SPRING, GROUND_DAMPER, COUPLING_SPRING, COUPLING_DAMPER = 1.0, 100.0, 0.1, 100.0, 0.1


def _header(name: str, description: str, signals: list[str], duration: float) -> str:
    return f'''name = "{name}"
description = "{description}"
source = "zencosim.scenes.topologies: m = {MASS} kg, k = {GROUND_SPRING} N/m, c = {GROUND_DAMPER} N s/m to ground; coupling elements {COUPLING_SPRING} N/m, {COUPLING_DAMPER} N s/m"

[manager]
duration = {duration!r}  # [s]
macro_step = 0.001    # [s]
extrapolation = 0

[outputs]
signals = {signals!r}
reference = "analytic"
'''.replace("'", '"')


def _mass(subsystem: str, body: str, x0: float) -> str:
    return f'''
[subsystems.{subsystem}]
model = "masses"
integrator = "symplectic_euler"
micro_step = 0.001
bodies.{body} = {{ mass = {MASS}, x0 = {x0!r}, v0 = 0.0 }}
effects.k = {{ type = "spring", bodies = ["{body}"], stiffness = {GROUND_SPRING} }}
effects.c = {{ type = "damper", bodies = ["{body}"], damping = {GROUND_DAMPER} }}
'''


def _coupling(name: str, force_side: str, motion_side: str, force: str, displacement: str, velocity: str) -> str:
    return f'''
[couplings.{name}]
type = "force_displacement"
force_side = "{force_side}"
motion_side = "{motion_side}"
force = "{force}"
displacement = "{displacement}"
velocity = "{velocity}"
effects.kc = {{ type = "spring", stiffness = {COUPLING_SPRING} }}
effects.cc = {{ type = "damper", damping = {COUPLING_DAMPER} }}
'''


def _check(n: int) -> None:
    if not isinstance(n, int) or n < 2:
        raise ValueError(f"expected at least 2 subsystems, got {n!r}")


def mass_chain(n: int, duration: float = 10.0) -> str:
    """A chain of ``n`` masses, one per subsystem (module text)."""
    _check(n)
    text = _header("mass_chain" if n == 5 else f"mass_chain_{n}",
                   f"A chain of {n} masses, one per subsystem, S<i> the force side of its coupling to S<i+1>",
                   [f"x{n}", "f1"], duration)
    text += "".join(_mass(f"S{i}", f"m{i}", 0.1 if i == 1 else 0.0) for i in range(1, n + 1))
    text += "".join(_coupling(f"c{i}", f"S{i}.m{i}", f"S{i + 1}.m{i + 1}", f"f{i}", f"x{i + 1}", f"v{i + 1}")
                    for i in range(1, n))
    return text


def mass_star(n: int, duration: float = 10.0) -> str:
    """A hub and ``n - 1`` leaves, one mass per subsystem (module text)."""
    _check(n)
    text = _header(f"mass_star_{n}", f"A star of {n} masses: a hub H and {n - 1} leaves, each the force side of its "
                   "coupling to the hub", ["xh", "f1"], duration)
    text += _mass("H", "mh", 0.0)
    text += "".join(_mass(f"S{i}", f"m{i}", 0.1 if i == 1 else 0.0) for i in range(1, n))
    text += "".join(_coupling(f"c{i}", f"S{i}.m{i}", "H.mh", f"f{i}", "xh", "vh") for i in range(1, n))
    return text


if __name__ == "__main__":
    kinds = {"chain": mass_chain, "star": mass_star}
    if len(sys.argv) != 3 or sys.argv[1] not in kinds or not sys.argv[2].isdigit():
        sys.exit("usage: python -m zencosim.scenes.topologies chain|star N > scene.toml")
    sys.stdout.write(kinds[sys.argv[1]](int(sys.argv[2])))
