"""The other direction: the FMU scenes of ``zencosim examples`` written as OSP system structures
(tests/interop/scene_osp.py) and run by libcosim and by zencosim: the same answer.

The example oscillator FMU's ``fc`` output is the force of its coupling element on the remote point, the
value the other instance's ``f_in`` applies with +: libcosim copies it unchanged, so libcosim's NRMS on
two_mass_damped_fmu is paper 000's 0.045434 only when that convention holds.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("libcosimpy")
pytest.importorskip("fmpy")

import zencosim  # noqa: E402
from tests.interop.libcosim_oracle import run_osp  # noqa: E402
from tests.interop.measures import (  # noqa: E402
    AGREEMENT,
    LIBCOSIM_NRMS,
    analytic_x2,
    coupling_of,
    largest_difference,
    nrms,
    zencosim_signals,
)
from tests.interop.peer_pair import write_system  # noqa: E402
from tests.interop.scene_osp import write_osp  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="building the example FMUs needs gcc")

SCENES = ("two_mass_damped_fmu", "double_oscillator_fmu")  # the explicit FMI 2.0 Co-Simulation examples


@pytest.fixture(scope="module")
def runs(examples) -> dict:
    """Per scene: the OSP file, libcosim's run of it, zencosim's run of it, zencosim's run of the TOML scene."""
    found = {}
    for name in SCENES:
        osp = write_osp(examples / f"{name}.toml", examples / f"{name}_osp.xml")
        scene = zencosim.load_scene(osp)
        force_side, motion_side = list(scene.subsystems)
        theirs = run_osp(osp, 10.0, [(motion_side, "x"), (motion_side, "v"), (force_side, "fc")])
        theirs = {"x2": theirs[(motion_side, "x")], "v2": theirs[(motion_side, "v")], "fc": theirs[(force_side, "fc")]}
        found[name] = (osp, theirs, zencosim_signals(zencosim.run(scene), coupling_of(scene)),
                       zencosim.run(zencosim.load_scene(examples / f"{name}.toml")))
    return found


@pytest.mark.parametrize("name", SCENES)
def test_libcosim_and_zencosim_give_one_answer_on_the_examples_osp(runs, name):
    _, theirs, ours, _ = runs[name]
    for signal in ("x2", "v2", "fc"):
        assert largest_difference(ours[signal], theirs[signal]) <= AGREEMENT, signal


def test_libcosim_on_the_example_fmus_has_paper_000s_error(runs):
    _, theirs, _, _ = runs["two_mass_damped_fmu"]
    assert nrms(theirs["x2"], analytic_x2()) == pytest.approx(LIBCOSIM_NRMS, abs=1e-6)


def test_the_example_fmus_and_the_peer_pair_agree_under_libcosim(runs, tmp_path):
    """Two FMUs written apart, one system: libcosim gives one answer (to rounding) for both."""
    path = write_system(tmp_path / "plain", "plain")
    peer = run_osp(path, 10.0, [("mass2", "x2"), ("mass1", "fc")])
    _, theirs, _, _ = runs["two_mass_damped_fmu"]
    assert largest_difference(theirs["x2"], peer[("mass2", "x2")]) <= AGREEMENT
    assert largest_difference(theirs["fc"], peer[("mass1", "fc")]) <= AGREEMENT


@pytest.mark.parametrize("name", SCENES)
def test_the_imported_osp_file_is_the_toml_scene(runs, name):
    """zencosim runs the OSP file it is given as it runs the scene it came from, bit for bit."""
    _, _, ours, toml = runs[name]
    force = "fc" if name == "two_mass_damped_fmu" else "f"
    assert np.array_equal(ours["x2"], toml.signal("x2").values)
    assert np.array_equal(ours["v2"], toml.signal("v2").values)
    assert np.array_equal(ours["fc"], toml.signal(force).values)
