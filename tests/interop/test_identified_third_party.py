"""The largest stable step of a third-party FMU loop, predicted by the identified exact discrete analysis
(``manager.analysis.stable_step``) and found by bisecting runs.

The loop is ``tests/interop/pythonfmu_pair.py``'s: a PI controller exported with pythonfmu (it cannot save its
state: each probe instantiates it anew) positioning the example oscillator FMU, through two signal connections,
with a damped plant (c = 10 N s/m) so that the boundary is sharp: one step past it ρ − 1 = 1.3e-2 per step.

Runs are bisected as ``tests/interop/bisection.py`` says: ``RUN_STEPS`` steps from x = 0, growing when x's
deviation from the setpoint (the loop's equilibrium: the controller integrates the error) over the last third
exceeds that over the middle third; at 1 % off the boundary the critical mode changes by ρ^100 ≈ e^{±1.3}
between the two, the other modes have decayed by 1e-5. The bracket grows by doubling from the scene's 10 ms,
then bisects to 0.25 % of its lower end.

The same controller positions axis 0 of crane-fmu's ``HarmonicOscillator6D.fmu`` (component-model; it integrates
each step with scipy's ``solve_ivp``, RK45 at a relative tolerance of 1e-3, and cannot save its state either) in
an OSP file of plain connections, x[0] -> position and force -> f[0], with c[0] = 10 N s/m (m = k = 1): one
percent past the boundary ρ − 1 = 3.9e-3 a step, the next mode's |λ| = 0.90 (of the exact zero-order-hold loop,
whose boundary is 0.42698 s). The runs start from 0.1 s (300 steps of 10 ms, 3 s, end within the transient, its
slowest mode -0.27 1/s, which the criterion reads as growth). The prediction's bracket is narrowed to the runs' 0.25 % only: the
target is 1 %, and each of its steps identifies the oscillator anew.
"""
from __future__ import annotations

import shutil

import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu", reason="pythonfmu exports the controller FMU (pip install pythonfmu)")

from tests.interop.bisection import bisected_runs  # noqa: E402
from tests.interop.pythonfmu_pair import (  # noqa: E402
    CONTROLLER_START,
    build_controller,
    write_plain_osp,
    write_scene,
)
from tests.interop.test_third_party import crane_fmu  # noqa: E402
from zencosim.manager.analysis import stable_step  # noqa: E402
from zencosim.manager.analysis.stable_step import largest_stable_step  # noqa: E402
from zencosim.manager.scene.load import Scene, load_scene  # noqa: E402

RUN_STEPS = 300
RUN_TOLERANCE = 2.5e-3  # relative width of the runs' final bracket
DAMPED_PLANT = ["subsystems.plant.start.c=10.0"]
CRANE_STEP = 0.1  # [s] the crane loop's base step, where the bisections start
CRANE_START = {"c[0]": 10.0}


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


@pytest.fixture(scope="module")
def crane_loop(tmp_path_factory) -> Scene:
    oscillator = crane_fmu("HarmonicOscillator6D")
    root = tmp_path_factory.mktemp("identified_crane")
    controller = build_controller(root / "build")
    osp = write_plain_osp(root, CRANE_STEP, {"osc": (oscillator, CRANE_STEP, CRANE_START),
                                             "controller": (controller, CRANE_STEP, CONTROLLER_START)},
                          (("osc", "x[0]", "controller", "position"), ("controller", "force", "osc", "f[0]")))
    return load_scene(str(osp), ['subsystems.osc.outputs="all"'])


@pytest.mark.slow
def test_the_predicted_largest_stable_step_of_a_pythonfmu_loop_is_the_one_runs_find(loop):
    predicted = largest_stable_step(loop)
    assert predicted.unanalysable == 0
    low, high = bisected_runs(loop, "x", CONTROLLER_START["setpoint"], RUN_STEPS, RUN_TOLERANCE)
    found = 0.5 * (low + high) * 1e-9
    assert predicted.largest_stable == pytest.approx(found, rel=0.01)


@pytest.mark.slow
def test_the_predicted_largest_stable_step_of_a_crane_fmu_loop_is_the_one_runs_find(crane_loop, monkeypatch):
    monkeypatch.setattr(stable_step, "STEP_TOLERANCE", RUN_TOLERANCE)
    predicted = largest_stable_step(crane_loop)
    assert predicted.unanalysable == 0
    low, high = bisected_runs(crane_loop, "x[0]", CONTROLLER_START["setpoint"], RUN_STEPS, RUN_TOLERANCE)
    found = 0.5 * (low + high) * 1e-9
    assert predicted.largest_stable == pytest.approx(found, rel=0.01)
