"""crane-fmu's own ECCO system (CraneOnOscillatorSystemStructure.xml: its MobileCraneStraight.fmu's torque[0] and
d_angular[0] bonded to HarmonicOscillator6D.fmu's f[3] and v[3]) with units stated by the scene.

The oscillator declares every variable "dimensionless" and the crane its angular velocity as pint's "radian /
second" without the radian exponent (s-1): the import refuses the bond until ``--set
subsystems.<name>.units.<variable>=UNIT`` states them; then it is a rotational bond whose residual power is
monitored. Both FMUs write ``<Unknown>`` without ``dependencies``: the loop they form starts as libcosim starts
it (docs/numerics.md), so the authors' files run as they are shipped.
"""
from __future__ import annotations

import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

pytest.importorskip("fmpy")

import zencosim  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
UNITS = ("--set", "subsystems.osc.units.f[3]=N.m", "--set", "subsystems.osc.units.v[3]=rad/s",
         "--set", "subsystems.crane.units.d_angular[0]=rad/s")


@pytest.fixture(scope="module")
def system() -> Path:
    try:
        distribution = metadata.distribution("crane-fmu")
    except metadata.PackageNotFoundError:
        pytest.skip("crane-fmu is not installed (pip install 'crane-fmu>=0.2'): its FMUs come with it")
    source = Path(distribution.locate_file("examples"))
    if not (source / "CraneOnOscillatorSystemStructure.xml").is_file():
        pytest.skip(f"crane-fmu {distribution.version} ships no CraneOnOscillatorSystemStructure.xml")
    return source / "CraneOnOscillatorSystemStructure.xml"


def _overrides(arguments: tuple[str, ...]) -> list[str]:
    return list(arguments[1::2])


def test_the_dimensionless_bond_is_refused_until_the_scene_states_its_units(system):
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(system)
    assert "connects variables of different quantities: dimensionless, energy" in str(caught.value)
    scene = zencosim.load_scene(system, _overrides(UNITS))
    (bond,) = scene.couplings.values()
    assert bond.kind == "force_displacement" and bond.settings.domain == "rotational"
    assert scene.replaced_units == {"crane.d_angular[0]": {"declared": "radian / second", "scene": "rad/s"},
                                    "osc.v[3]": {"declared": "dimensionless", "scene": "rad/s"},
                                    "osc.f[3]": {"declared": "dimensionless", "scene": "N.m"}}


def test_a_stated_unit_that_contradicts_the_fmus_real_unit_is_refused_by_key(system):
    """crane.torque[0] declares kg m2 s-2: a scene cannot make it an angular velocity."""
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(system, [*_overrides(UNITS), "subsystems.crane.units.torque[0]=rad/s"])
    assert ("subsystems.crane.units.torque[0]: torque[0]: the FMU MobileCraneStraight.fmu declares "
            "[kilogram * meter ** 2 / second ** 2] (kg m2 s-2), the scene [rad/s] (s-1 rad): not the same quantity"
            ) in str(caught.value)


@pytest.mark.slow
@pytest.mark.multiprocess
def test_the_crane_on_its_oscillator_runs_with_residual_power_at_its_bond(system, tmp_path):
    """Tilted by 0.1 rad (angular[0], an input no connection feeds), the crane's torque drives the oscillator, whose
    angular velocity turns the crane: power flows through the bond, so its residual energy is not zero. In a
    process of its own: the pythonfmu FMUs run in the interpreter that loads them (test_third_party.py)."""
    summary = tmp_path / "summary.json"
    run = subprocess.run([sys.executable, "-m", "zencosim", "run", str(system), *UNITS, "--set", "manager.duration=0.01",
                          "--set", "subsystems.crane.start.angular[0]=0.1", "--summary", str(summary), "--quiet"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads(summary.read_text())
    assert result["residual_energy"]["forceX-velocityX"] != 0.0 and not result["diverged"]
    assert result["replaced_units"]["osc.f[3]"] == {"declared": "dimensionless", "scene": "N.m"}


def test_the_run_says_which_outputs_out_leaves_out_and_how_to_get_them(system):
    """An import publishes the couplings' signals only (its digest and recordings stay what they were): the run
    counts the FMUs' other outputs (crane 15 and osc 12, less the bond's torque[0] and v[3]) in one line."""
    from zencosim.cli.run import _unpublished_outputs

    assert _unpublished_outputs(zencosim.load_scene(system, _overrides(UNITS))) == (
        "the tables hold the couplings' signals; not the other outputs of crane (14), osc (11): "
        "--set subsystems.<name>.outputs=all adds them")
    every = zencosim.load_scene(system, [*_overrides(UNITS), "subsystems.crane.outputs=all",
                                         "subsystems.osc.outputs=all"])
    assert _unpublished_outputs(every) is None
