"""The largest stable step of a third-party FMU loop, predicted by the identified exact discrete analysis
(``manager.analysis.stable_step``) and found by bisecting runs (issue 41, item 3).

The loop is ``tests/interop/pythonfmu_pair.py``'s: a PI controller exported with pythonfmu (it cannot save its
state: each probe instantiates it anew) positioning the example oscillator FMU, through two signal connections,
with a damped plant (c = 10 N s/m) so that the boundary is sharp: one step past it ρ − 1 = 1.3e-2 per step.

Runs are bisected on the same grid of steps as the prediction, every micro-step equal to the macro-step. A run
of ``RUN_STEPS`` steps from x = 0 grows when the largest deviation from the setpoint (the loop's equilibrium:
the controller integrates the error) over its last third exceeds that over its middle third; at 1 % off the
boundary the critical mode changes by ρ^100 ≈ e^{±1.3} between the two, the other modes have decayed by 1e-5.
The bracket of runs grows by doubling from the scene's 10 ms, then bisects to 0.25 % of its lower end.
"""
from __future__ import annotations

import shutil
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu", reason="pythonfmu exports the controller FMU (pip install pythonfmu)")

from tests.interop.pythonfmu_pair import CONTROLLER_START, build_controller, write_scene  # noqa: E402
from zencosim.manager.analysis.stable_step import largest_stable_step, scaled_scene, step_quantum_ns  # noqa: E402
from zencosim.manager.results.tables import record_signals  # noqa: E402
from zencosim.manager.run import execute  # noqa: E402
from zencosim.manager.scene.load import Scene, load_scene  # noqa: E402

RUN_STEPS = 300
RUN_TOLERANCE = 2.5e-3  # relative width of the runs' final bracket
DAMPED_PLANT = ["subsystems.plant.start.c=10.0"]


@pytest.fixture(scope="module")
def loop(tmp_path_factory) -> Scene:
    if shutil.which("gcc") is None:
        pytest.skip("building the example oscillator FMU needs gcc")
    from zencosim.examples.write import write_examples

    root = tmp_path_factory.mktemp("identified_pair")
    write_examples(root / "examples")
    system = root / "system"
    system.mkdir()
    scene = write_scene(system, root / "examples" / "oscillator_fmi2.fmu", build_controller(root / "build"))
    return load_scene(str(scene), DAMPED_PLANT)


def _run_grows(scene: Scene, step_ns: int) -> bool:
    """Whether a run of ``RUN_STEPS`` steps of ``step_ns`` moves away from the setpoint (see the module text)."""
    scaled = scaled_scene(scene, step_ns)
    scaled = replace(scaled, manager=replace(scaled.manager, duration=RUN_STEPS * step_ns * 1e-9))
    record, _ = execute(scaled, "inproc")
    deviation = np.abs(record_signals(record)["x"].values - CONTROLLER_START["setpoint"])
    third = deviation.size // 3
    return bool(deviation[2 * third:].max() > deviation[third:2 * third].max())


def _bisected_runs(scene: Scene) -> tuple[int, int]:
    """The bracket [largest stable, smallest growing] of macro-steps [ns] found by runs alone."""
    quantum = step_quantum_ns(scene)
    low = scene.manager.macro_step_ns // quantum
    assert not _run_grows(scene, low * quantum)
    high = 2 * low
    while not _run_grows(scene, high * quantum):
        low, high = high, 2 * high
    while high - low > RUN_TOLERANCE * low:
        middle = (low + high) // 2
        if _run_grows(scene, middle * quantum):
            high = middle
        else:
            low = middle
    return low * quantum, high * quantum


@pytest.mark.slow
def test_the_predicted_largest_stable_step_of_a_pythonfmu_loop_is_the_one_runs_find(loop):
    predicted = largest_stable_step(loop)
    assert predicted.unanalysable == 0
    low, high = _bisected_runs(loop)
    found = 0.5 * (low + high) * 1e-9
    assert predicted.largest_stable == pytest.approx(found, rel=0.01)
