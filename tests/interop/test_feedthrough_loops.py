"""Feedback loops of FMUs that declare no output dependencies (pythonfmu 0.7 and component-model write
``<Unknown index="n"/>``, which FMI reads as "depends on every input"): zencosim initialises them as libcosim does
(``manager.plan.run_plan._init_rounds``) and gives libcosim's answer on the same OSP file, single- and multi-rate;
``subsystems.X.feedthrough`` states what a modelDescription omits; a loop of declared feedthrough is refused.

Tolerance: ``AGREEMENT`` (1e-12) of each signal's range. The whole difference is the step handed to doStep
(libcosim's t_{k+1} - t_k of rounded time points, zencosim's exact step; docs/interop.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu", reason="pythonfmu exports the loop's FMUs (pip install pythonfmu)")
pytest.importorskip("libcosimpy", reason="libcosim is the oracle (pip install libcosimpy)")

import zencosim  # noqa: E402
from zencosim.manager.assembly import plan_scene  # noqa: E402
from tests.interop.fmu_loops import (  # noqa: E402
    CRANE_CONNECTIONS,
    PD_CONNECTIONS,
    PD_SOURCE,
    PLANT_SOURCE,
)
from tests.interop.libcosim_oracle import run_osp  # noqa: E402
from tests.interop.measures import AGREEMENT  # noqa: E402
from tests.interop.pythonfmu_pair import build_fmu, write_plain_osp  # noqa: E402
from tests.interop.test_third_party import crane_fmu  # noqa: E402

DURATION = 1.0  # [s] the PD loop
CRANE_DURATION = 0.3  # [s] (HarmonicOscillator6D calls scipy's solve_ivp every step)
STEP = 0.01  # [s] the base step
# per system: simulator -> (the variables compared, its stepSize in base steps: single rate, multi-rate)
PD_VARIABLES = {"controller": (("force",), (1, 2)), "plant": (("x", "v", "x_mount"), (1, 1))}
CRANE_VARIABLES = {"drive": (("f[0]", "f[1]", "f[2]"), (1, 1)),
                   "osc": (tuple(f"{q}[{i}]" for q in "xv" for i in range(3)), (1, 2))}


@pytest.fixture(scope="module")
def pd_fmus(tmp_path_factory) -> dict[str, Path]:
    build = tmp_path_factory.mktemp("pd_build")
    return {"controller": build_fmu(build, "zencosim_pd_controller", PD_SOURCE),
            "plant": build_fmu(build, "zencosim_mass_spring", PLANT_SOURCE)}


def system(directory: Path, fmus: dict[str, Path], variables: dict, connections: tuple, rate: int) -> Path:
    """The OSP file of a loop, each simulator at its stepSize of ``rate`` (0: single rate, 1: multi-rate)."""
    return write_plain_osp(directory, STEP, {name: (fmu, STEP * variables[name][1][rate], {})
                                             for name, fmu in fmus.items()}, connections)


def deviations(osp: Path, variables: dict, result, duration: float) -> dict[str, float]:
    """Per variable: max |zencosim - libcosim| over libcosim's range, at libcosim's samples (each simulator after its
    steps; zencosim publishes every output as a signal of its name, ``outputs = "all"``)."""
    found = {}
    for simulator, (names, _) in variables.items():
        theirs = run_osp(osp, duration, [(simulator, name) for name in names])
        for name in names:
            ours = result.signal(name)
            assert np.allclose(ours.time, theirs.time, rtol=0, atol=1e-12), name
            assert np.ptp(theirs[(simulator, name)]) > 0, name  # the loop moves it
            found[f"{simulator}.{name}"] = float(np.max(np.abs(ours.values - theirs[(simulator, name)]))
                                                 / np.ptp(theirs[(simulator, name)]))
    return found


def run_zencosim(osp: Path, variables: dict, duration: float, bus: str = "inproc", extra: tuple[str, ...] = ()):
    overrides = [f"manager.duration={duration}", *(f'subsystems.{name}.outputs="all"' for name in variables), *extra]
    return zencosim.run(zencosim.load_scene(str(osp), overrides), bus=bus)


CONTROLLER_DECLARED = 'subsystems.controller.feedthrough={ force = ["position", "velocity"] }'


@pytest.mark.parametrize("rate, stated", [(0, ()), (1, ()), (0, (CONTROLLER_DECLARED,))],
                         ids=["single-rate", "multi-rate", "controller-declared"])
def test_a_pythonfmu_pd_loop_gives_libcosims_answer(pd_fmus, rate, stated, tmp_path):
    """The PD controller and the mass–spring: the same as libcosim, initial values included, which take
    libcosim's N + 1 = 3 passes. The loop stays libcosim's with the controller's feedthrough declared by the scene:
    the plant's is still undeclared."""
    osp = system(tmp_path, pd_fmus, PD_VARIABLES, PD_CONNECTIONS, rate)
    result = run_zencosim(osp, PD_VARIABLES, DURATION, extra=stated)
    found = deviations(osp, PD_VARIABLES, result, DURATION)
    assert max(found.values()) <= AGREEMENT, found
    force, x_mount = result.signal("force").values[0], result.signal("x_mount").values[0]
    assert force != 20.0 * (1.0 - 0.5) and x_mount != 0.5  # the initial values went through the loop


@pytest.mark.slow
@pytest.mark.parametrize("rate", [0, 1], ids=["single-rate", "multi-rate"])
def test_crane_fmus_driving_force_and_oscillator_loop_gives_libcosims_answer(rate, tmp_path):
    fmus = {"drive": crane_fmu("DrivingForce"), "osc": crane_fmu("HarmonicOscillator6D")}
    osp = system(tmp_path, fmus, CRANE_VARIABLES, CRANE_CONNECTIONS, rate)
    found = deviations(osp, CRANE_VARIABLES, run_zencosim(osp, CRANE_VARIABLES, CRANE_DURATION), CRANE_DURATION)
    assert max(found.values()) <= AGREEMENT, found


@pytest.mark.multiprocess
def test_the_pd_loop_gives_one_digest_on_both_buses(pd_fmus, tmp_path):
    osp = system(tmp_path, pd_fmus, PD_VARIABLES, PD_CONNECTIONS, 1)
    assert run_zencosim(osp, PD_VARIABLES, DURATION, "zenoh").digest == run_zencosim(osp, PD_VARIABLES, DURATION).digest


def test_a_loop_of_declared_feedthrough_is_refused_naming_the_keys(pd_fmus, tmp_path):
    """The feedthrough key declares what the getters do: the loop is then a real one, refused, naming who says so;
    ``{}`` on the plant (its x_mount declared free of f, wrongly) lets it start in one round."""
    osp = system(tmp_path, pd_fmus, PD_VARIABLES, PD_CONNECTIONS, 0)
    declared = [CONTROLLER_DECLARED, 'subsystems.plant.feedthrough={ x_mount = ["f"] }']
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.run(zencosim.load_scene(str(osp), declared))
    assert [(p.key, p.reason) for p in caught.value.problems] == [(
        "couplings", "outputs with direct feedthrough form an algebraic loop: controller.controller_force <- "
        "plant.plant_x_mount <- controller.controller_force (feedthrough: controller's as "
        "subsystems.controller.feedthrough states it; plant's as subsystems.plant.feedthrough states it); an explicit "
        "scheme cannot initialise them")]
    scene = zencosim.load_scene(str(osp), [declared[0], "subsystems.plant.feedthrough={}"])
    assert plan_scene(scene)[0].init_rounds[0][0].ready == ()


def test_the_feedthrough_key_naming_an_unknown_variable_is_refused(tmp_path):
    """Each wrong name is one problem naming the file, the key and what the FMU has (``zencosim check`` prints each
    on a line of its own and exits with status 2, as for every scene problem)."""
    fmus = {"drive": crane_fmu("DrivingForce"), "osc": crane_fmu("HarmonicOscillator6D")}
    osp = system(tmp_path, fmus, CRANE_VARIABLES, CRANE_CONNECTIONS, 0)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(str(osp), ['subsystems.osc.feedthrough={ "v[0]" = ["force", "f[0]"], "f[1]" = [] }'])
    assert caught.value.path == str(osp)
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        ("subsystems.osc.feedthrough.v[0]", "the FMI 2.0 Co-Simulation has no variable 'force'; its inputs: f[0], "
                                            "f[1], f[2], f[3], f[4], f[5]"),
        ("subsystems.osc.feedthrough.f[1]", "f[1] is input, not an output; its outputs: x[0], x[1], x[2], x[3], "
                                            "x[4], x[5], v[0], v[1], v[2], v[3], v[4], v[5]")]


def test_check_shows_the_feedthrough_the_scene_states_and_the_undeclared(pd_fmus, tmp_path, capsys):
    from zencosim.cli.main import build_parser

    osp = system(tmp_path, pd_fmus, PD_VARIABLES, PD_CONNECTIONS, 0)
    args = build_parser("check").parse_args(["check", str(osp), "--set", "subsystems.plant.feedthrough={ v = [] }"])
    assert args.handler(args) == 0
    lines = [" ".join(line.split()) for line in capsys.readouterr().out.splitlines()]
    assert "outputs: controller_force [1] (feedthrough undeclared: every input)" in lines
    assert "outputs: plant_x_mount [1], plant_v [1]" in lines
    assert "feedthrough (subsystems.plant.feedthrough): v <- none; the other outputs: none" in lines
