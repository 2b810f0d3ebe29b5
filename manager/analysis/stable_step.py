"""The largest stable communication step of a scene's explicit scheme: bisection on the macro-step of the exact
discrete scheme's verdict ``ρ(Ψ) <= 1`` (``manager.analysis.discrete``), its FMUs and Python models identified
anew at every step (``manager.analysis.identified``).

The scene is scaled as a whole: the macro-step ``T`` changes, every subsystem keeps its communication ratio and its
number of micro-steps per communication step (a scene with ``micro_step = macro_step`` keeps them equal, as paper
000 §5.1 steps). ``T`` moves on the grid of whole nanoseconds where every micro-step is whole. From the scene's own
step, the bracket grows by doubling while the scheme is stable (or halves while it is not), then bisection narrows
it until its width is at most ``STEP_TOLERANCE`` of its lower end (or one grid step). The answer assumes one
stability boundary between the first stable and the first unstable step of the bracket (a scheme stable again at
larger steps is not looked for). A step at which the scheme cannot be analysed (a subsystem that cannot be identified
there, one whose responses overflow) counts as unstable; the report says how many did.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from zencosim.manager.analysis.discrete import DiscreteScheme, LinearSceneError, uncompensated_scheme
from zencosim.manager.scene.load import Scene

STEP_TOLERANCE = 1e-4  # relative width of the final bracket [largest stable, smallest unstable]
MAX_DOUBLINGS = 40  # of the bracket's search (a factor of 2^40 ~ 1e12 either way of the scene's step)


@dataclass(frozen=True)
class StableStep:
    """The bracket of the stability boundary: ``largest_stable < boundary <= smallest_unstable`` [s]."""

    largest_stable: float | None  # None: unstable at every step tried
    smallest_unstable: float | None  # None: stable at every step tried
    evaluations: int  # discrete schemes built
    unanalysable: int  # steps where the scheme could not be built (counted unstable)

    def to_dict(self) -> dict:
        return {"largest_stable": self.largest_stable, "smallest_unstable": self.smallest_unstable,
                "relative_tolerance": STEP_TOLERANCE, "evaluations": self.evaluations,
                "unanalysable": self.unanalysable}


def step_quantum_ns(scene: Scene) -> int:
    """The grid of macro-steps [ns] on which every subsystem's micro-step is a whole number of nanoseconds."""
    quantum = 1
    for sub in scene.subsystems.values():
        micro_steps = scene.comm_step_ns(sub.name) // sub.settings.micro_step_ns  # per communication step
        quantum = math.lcm(quantum, micro_steps // math.gcd(micro_steps, sub.settings.comm_ratio))
    return quantum


def scaled_scene(scene: Scene, macro_step_ns: int) -> Scene:
    """``scene`` with the macro-step ``macro_step_ns`` and every micro-step scaled with it."""
    subsystems = {}
    for name, sub in scene.subsystems.items():
        micro_steps = scene.comm_step_ns(name) // sub.settings.micro_step_ns
        micro_ns = macro_step_ns * sub.settings.comm_ratio // micro_steps
        subsystems[name] = replace(sub, settings=replace(sub.settings, micro_step=micro_ns * 1e-9))
    return replace(scene, manager=replace(scene.manager, macro_step=macro_step_ns * 1e-9), subsystems=subsystems)


def largest_stable_step(scene: Scene, own: DiscreteScheme | None = None) -> StableStep:
    """The bracket of the largest stable macro-step of ``scene`` run without a compensator (see the module text);
    ``own``: its ``uncompensated_scheme`` at its own step, where the caller has built it already."""
    quantum = step_quantum_ns(scene)
    j = scene.manager.macro_step_ns // quantum
    verdicts: dict[int, bool] = {} if own is None else {j: own.stable}
    unanalysable = 0

    def stable(j: int) -> bool:
        nonlocal unanalysable
        if j not in verdicts:
            try:
                verdicts[j] = uncompensated_scheme(scaled_scene(scene, j * quantum)).stable
            except (LinearSceneError, ArithmeticError):
                verdicts[j], unanalysable = False, unanalysable + 1
        return verdicts[j]

    if stable(j):
        low, high = j, 2 * j
        for _ in range(MAX_DOUBLINGS):
            if not stable(high):
                break
            low, high = high, 2 * high
        else:
            return StableStep(low * quantum * 1e-9, None, len(verdicts), unanalysable)
    else:
        low, high = j // 2, j
        while low >= 1 and not stable(low):
            low, high = low // 2, low
        if low < 1:
            return StableStep(None, high * quantum * 1e-9, len(verdicts), unanalysable)
    while high - low > 1 and high - low > STEP_TOLERANCE * low:
        middle = (low + high) // 2
        if stable(middle):
            low = middle
        else:
            high = middle
    return StableStep(low * quantum * 1e-9, high * quantum * 1e-9, len(verdicts), unanalysable)
