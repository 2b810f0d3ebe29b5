"""zencosim's energy-controlled macro-step against libcosim's ECCO on the same OspSystemStructure.xml (issue 27).

The peer pair (tests/interop/peer_pair.py: two FMUs built here, paper 000's two_mass_damped) with libcosim's
``ecco`` algorithm and an EccoConfiguration; libcosimpy 0.0.6 runs it, zencosim imports it
(manager.step_control = "energy") and runs it. What holds: every macro-step of the run has the length libcosim
gave it, to the nanosecond, and the values agree to rounding (libcosim hands ``fmi2DoStep`` the difference of two
rounded time points, zencosim the step itself: tests/interop/test_libcosim.py measures the same 1e-14 at a fixed
step), held to ``AGREEMENT`` (1e-12 of each signal's largest magnitude). Where they part: libcosim's last step
runs past the end time, zencosim's is cut to end there.

A libcosim quirk the oracle works around: its ECCO reads each bond's input variables with ``get_real``, which
libcosim allows only for variables exposed for getting; nothing exposes an input but an observer, so the inputs of
the bond are observed too (else libcosim fails: "Variable with reference 5 not found in exposed variables").
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("libcosimpy")
pytest.importorskip("fmpy")

import zencosim
from tests.interop.libcosim_oracle import run_osp
from tests.interop.measures import AGREEMENT, largest_difference, zencosim_signals
from tests.interop.peer_pair import ecco_configuration, write_system

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="building the FMUs needs gcc")

END_TIME = 2.0  # [s]
ECCO = ecco_configuration({"SafetyFactor": 0.8, "StepSize": 0.0001, "MinimumStepSize": 0.0001, "MaximumStepSize": 0.01,
                           "MinimumChangeRate": 0.2, "MaximumChangeRate": 1.5, "ProportionalGain": 0.2,
                           "IntegralGain": 0.15, "RelativeTolerance": "1e-3", "AbsoluteTolerance": 1.0})
SIGNALS = {"x2": ("mass2", "x2"), "v2": ("mass2", "v2"), "fc": ("mass1", "fc")}
BOND_INPUTS = [("mass2", "fc_in"), ("mass1", "v2_in")]  # observed so that libcosim's ECCO may read them


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    path = write_system(tmp_path_factory.mktemp("ecco_pair"), "plain")
    text = path.read_text().replace("<Algorithm>fixedStep</Algorithm>", "<Algorithm>ecco</Algorithm>")
    text = text.replace("<EndTime>10.0</EndTime>", f"<EndTime>{END_TIME!r}</EndTime>")
    path.write_text(text.replace("</OspSystemStructure>", ECCO + "</OspSystemStructure>"))
    return path


@pytest.fixture(scope="module")
def runs(system):
    theirs = run_osp(system, END_TIME, [*SIGNALS.values(), *BOND_INPUTS])
    return theirs, zencosim.run(zencosim.load_scene(system))


def test_every_macro_step_has_the_length_libcosims_ecco_gives_it(runs):
    theirs, ours = runs
    ticks = np.asarray(ours.record.point_ticks)  # macro_step 1 ns: nanoseconds
    their_ns = np.round(theirs.time * 1e9).astype(np.int64)
    assert len(ticks) == len(their_ns)
    assert np.array_equal(ticks[:-1], their_ns[:-1])
    assert ticks[-1] == round(END_TIME * 1e9) < their_ns[-1]  # libcosim's last step ends past the end time
    steps = np.diff(ticks[:-1])
    assert len(np.unique(steps)) > 1000 and steps.min() == 100_000 and steps.max() > 3_000_000  # they vary


def test_the_values_are_libcosims_up_to_rounding(runs):
    theirs, ours = runs
    mine = zencosim_signals(ours, "c")
    for name, key in SIGNALS.items():
        assert largest_difference(mine[name][:-1], theirs[key][:-1]) <= AGREEMENT, name


def test_the_summary_reports_the_steps_it_took(runs):
    _, ours = runs
    control = ours.summary["step_control"]
    steps = np.diff(np.asarray(ours.record.point_ticks)) * 1e-9
    assert control["macro_steps"] == ours.summary["steps"] == len(steps)
    assert (control["min_step"], control["max_step"]) == (steps.min(), steps.max())
    assert control["parameters"]["abs_tolerance"] == 1.0 and control["parameters"]["max_step_size"] == 0.01


def test_an_fmu_that_steps_at_a_fixed_size_is_refused_by_name(system, tmp_path):
    """canHandleVariableCommunicationStepSize="false": the FMU cannot take the varying macro-steps."""
    import zipfile

    directory = tmp_path / "fixed"
    shutil.copytree(system.parent, directory)
    fmu = directory / "mass2.fmu"
    with zipfile.ZipFile(system.parent / "mass2.fmu") as source, zipfile.ZipFile(fmu, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canHandleVariableCommunicationStepSize="true"',
                                    b'canHandleVariableCommunicationStepSize="false"')
            target.writestr(item, data)
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(directory / "OspSystemStructure.xml")
    assert {p.key: p.reason for p in caught.value.problems} == {
        "subsystems.mass2.fmu": "FMU mass2.fmu declares a fixed communication step (canHandleVariableCommunicationStepSize "
                                "false): it cannot take the varying macro-steps of manager.step_control = 'energy'"}
