"""The plain-Python floor of a co-simulation step: two_mass_damped's arithmetic as one inline loop over floats.

The same symplectic-Euler Jacobi scheme as the runtime runs for the scene (paper 000 §2.3, §5.1: ZOH inputs,
one micro-step per macro-step, the coupling force of S1 evaluated at the end of its step with the input it
held), written as one Python loop over floats: no messages, no numpy, no energy outputs. Nothing in Python
does the same work faster, so the runtime's time per step over this one says what the rest costs.
"""
from __future__ import annotations

import time

from zencosim.manager.scene.load import Scene


def parameters(scene: Scene) -> dict[str, float]:
    """Masses, springs, dampers, initial state and step of two_mass_damped (or a scene with its structure)."""
    doc = scene.resolved
    s1, s2, coupling = doc["subsystems"]["S1"], doc["subsystems"]["S2"], doc["couplings"]["c"]["effects"]
    return {"m1": s1["bodies"]["m1"]["mass"], "x1": s1["bodies"]["m1"]["x0"], "v1": s1["bodies"]["m1"]["v0"],
            "k1": s1["effects"]["k1"]["stiffness"], "c1": s1["effects"]["c1"]["damping"],
            "m2": s2["bodies"]["m2"]["mass"], "x2": s2["bodies"]["m2"]["x0"], "v2": s2["bodies"]["m2"]["v0"],
            "k2": s2["effects"]["k2"]["stiffness"], "c2": s2["effects"]["c2"]["damping"],
            "kc": coupling["kc"]["stiffness"], "cc": coupling["cc"]["damping"], "h": scene.manager.macro_step}


def floor_x2(p: dict[str, float], steps: int) -> list[float]:
    """x2 at every macro-step of the scheme (the runtime's x2 to rounding)."""
    m1, k1, c1, m2, k2, c2, kc, cc, h = (p[k] for k in ("m1", "k1", "c1", "m2", "k2", "c2", "kc", "cc", "h"))
    x1, v1, x2, v2 = p["x1"], p["v1"], p["x2"], p["v2"]
    fc = kc * (x2 - x1) + cc * (v2 - v1)  # S1's coupling force at t0, from S2's initial outputs
    trajectory = [x2]
    append = trajectory.append
    for _ in range(steps):
        x2_held, v2_held, fc_held = x2, v2, fc  # ZOH: both sides hold what the other sent at t_k
        v1 += h * (-k1 * x1 - c1 * v1 + kc * (x2_held - x1) + cc * (v2_held - v1)) / m1
        x1 += h * v1
        v2 += h * (-k2 * x2 - c2 * v2 - fc_held) / m2
        x2 += h * v2
        fc = kc * (x2_held - x1) + cc * (v2_held - v1)  # at t_k+1 with the input S1 held
        append(x2)
    return trajectory


def floor_step_s(scene: Scene, steps: int) -> float:
    """Wall time [s] per macro-step of the floor loop."""
    p = parameters(scene)
    start = time.perf_counter()
    floor_x2(p, steps)
    return (time.perf_counter() - start) / steps
