"""The largest stable communication step of a loop found by runs alone, to check the identified analysis'
prediction (``manager.analysis.stable_step.largest_stable_step``) against (issue 41, third-party targets).

Runs are bisected on the analysis' grid of steps (``step_quantum_ns``), every micro-step equal to the macro-step
(``scaled_scene``). A run of ``steps`` steps from the scene's start *grows* when the largest deviation of one
signal from the loop's equilibrium over its last third exceeds that over its middle third: at 1 % off the
boundary of a sharp loop (ρ − 1 ≈ 1e-2 a step one step past it) the critical mode changes by ρ^(steps/3) ≈ e^{±1}
between the thirds while the others have decayed. The bracket grows by doubling from the scene's macro-step, then
bisects to ``tolerance`` of its lower end.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from zencosim.manager.analysis.stable_step import scaled_scene, step_quantum_ns
from zencosim.manager.results.tables import record_signals
from zencosim.manager.run import execute
from zencosim.manager.scene.load import Scene


def run_grows(scene: Scene, step_ns: int, signal: str, equilibrium: float, steps: int) -> bool:
    """Whether a run of ``steps`` steps of ``step_ns`` moves ``signal`` away from ``equilibrium``."""
    scaled = scaled_scene(scene, step_ns)
    scaled = replace(scaled, manager=replace(scaled.manager, duration=steps * step_ns * 1e-9))
    record, _ = execute(scaled, "inproc")
    deviation = np.abs(record_signals(record)[signal].values - equilibrium)
    third = deviation.size // 3
    return bool(deviation[2 * third:].max() > deviation[third:2 * third].max())


def bisected_runs(scene: Scene, signal: str, equilibrium: float, steps: int, tolerance: float) -> tuple[int, int]:
    """The bracket [largest stable, smallest growing] of macro-steps [ns] found by runs alone."""
    def grows(multiple: int) -> bool:
        return run_grows(scene, multiple * quantum, signal, equilibrium, steps)

    quantum = step_quantum_ns(scene)
    low = scene.manager.macro_step_ns // quantum
    assert not grows(low), "the scene's own step already grows"
    high = 2 * low
    while not grows(high):
        low, high = high, 2 * high
    while high - low > tolerance * low:
        middle = (low + high) // 2
        if grows(middle):
            high = middle
        else:
            low = middle
    return low * quantum, high * quantum
