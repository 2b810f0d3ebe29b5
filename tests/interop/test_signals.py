"""Signal connections, transformations, unit conversions and a simulator alone, against libcosim (issue 24,
items 2 and 6): the peer FMUs (tests/interop/peer_pair.py, written for these tests, not by zencosim) in
OSP and SSP files (tests/interop/peer_systems.py) that zencosim imports and libcosim loads as they are.

* OSP, plain ``VariableConnection`` elements without ``powerBond``: signal couplings; the pair's three
  connections, and one signal alone (mass1's fc drives mass2, which sends nothing back).
* OSP, one simulator coupled to nothing: it runs free and publishes its outputs.
* SSP, mass1_own outputs the force on its own point; a ``ssc:LinearTransformation factor="-1"`` on the force
  connection gives mass2 the force on mass2: the bond's ``force_factor = -1``. libcosim's SSP loader applies
  the transformation (it gives the plain pair's answer bit for bit); FMPy's ``simulate_ssp`` does not
  (measured in docs/interop.md), so it is no oracle here.
* SSP, mass2_mm outputs x2 in mm and mass1 takes x2_in in m: zencosim converts at mass2's boundary.
  libcosim converts no units, so its reference is the same system with the conversion written as a
  ``LinearTransformation factor="0.001"`` (its answer without one runs away: x2_in 1000 times too large).

Tolerance: libcosim hands ``fmi2DoStep`` the step t_{k+1} - t_k of two rounded time points, zencosim the
exact 0.001 (docs/interop.md); the trajectories agree to AGREEMENT = 1e-12 of each signal's largest value
(measured: at most 2.4e-14). fc is a direct-feedthrough output; with constant-step ZOH both engines read it
at the same instant here, after the step's inputs are set (the replica master says so bit for bit).
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("libcosimpy")
pytest.importorskip("fmpy")

import zencosim  # noqa: E402
from tests.interop.libcosim_oracle import run_osp  # noqa: E402
from tests.interop.measures import AGREEMENT, largest_difference  # noqa: E402
from tests.interop.peer_pair import END_TIME, STEPS, write_system  # noqa: E402
from tests.interop.peer_systems import alone, oneway, write_ssd  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="building the FMUs needs gcc")

PAIR = (("mass2", "x2"), ("mass2", "v2"), ("mass1", "fc"))


def compare(result, theirs, names: dict[tuple[str, str], str], scale: dict[str, float] | None = None) -> dict:
    """The largest relative difference of each signal (zencosim's ``names[key]`` times ``scale``) from
    libcosim's ``key``; asserts the sample times agree."""
    differences = {}
    for key, name in names.items():
        signal = result.signal(name)
        assert np.allclose(signal.time, theirs.time, rtol=0.0, atol=1e-12)
        differences[name] = largest_difference(signal.values * (scale or {}).get(name, 1.0), theirs[key])
    return differences


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return tmp_path_factory.mktemp("signals")


# OSP: signals and a simulator alone -------------------------------------------------------------------------

def test_plain_variable_connections_are_signal_couplings_with_libcosims_answer(root):
    """The pair connected by three plain VariableConnections (no powerBond): three signal couplings, no bond,
    and the trajectories libcosim computes from the same file."""
    from tests.interop.replica import run_pair

    path = write_system(root / "unmarked", "unmarked")
    scene = zencosim.load_scene(path)
    assert {name: coupling.kind for name, coupling in scene.couplings.items()} == {
        "mass1_fc": "signal", "mass2_v2": "signal", "mass2_x2": "signal"}
    result = zencosim.run(scene)
    theirs = run_osp(path, END_TIME, PAIR)
    names = dict(zip(PAIR, ("mass2_x2", "mass2_v2", "mass1_fc")))
    differences = compare(result, theirs, names)
    assert max(differences.values()) <= AGREEMENT, differences
    as_zencosim = run_pair(path.parent, STEPS, step="zencosim")  # signals exchange when bonds do: bit for bit
    for (_, variable), name in names.items():
        assert np.array_equal(result.signal(name).values, as_zencosim[variable]), name


def test_one_signal_drives_a_mass_as_in_libcosim(root):
    """mass1.fc -> mass2.fc_in alone: mass1 oscillates on its own and drives mass2. mass2 is coupled, so it
    publishes only what couplings send; subsystems.mass2.outputs = "all" publishes x2 and v2 too."""
    path = oneway(root / "oneway")
    document, _ = zencosim.manager.scene.imports.import_system(path)
    assert document["couplings"] == {"mass1_fc": {"type": "signal", "output": "mass1.fc", "input": "mass2.fc_in"}}
    result = zencosim.run(zencosim.load_scene(path, {"subsystems.mass2.outputs": "all"}))
    theirs = run_osp(path, END_TIME, PAIR)
    differences = compare(result, theirs, dict(zip(PAIR, ("x2", "v2", "mass1_fc"))))
    assert max(differences.values()) <= AGREEMENT, differences
    assert np.max(np.abs(result.signal("x2").values)) > 0.1  # it was driven


def test_a_simulator_coupled_to_nothing_runs_free_as_in_libcosim(root):
    path = alone(root / "alone")
    scene = zencosim.load_scene(path)
    assert not scene.couplings
    result = zencosim.run(scene)
    theirs = run_osp(path, END_TIME, PAIR[:2])
    differences = compare(result, theirs, dict(zip(PAIR[:2], ("x2", "v2"))))
    assert max(differences.values()) <= AGREEMENT, differences
    assert result.signal("v2").values[0] == -100.0


# SSP: a transformed force, a unit conversion -------------------------------------------------------------------

@pytest.fixture(scope="module")
def ssp(root) -> dict:
    variants = ("plain", "own", "mm", "mm_transformed")
    return {variant: write_ssd(root / f"ssp_{variant}", variant) for variant in variants}


BOND = {("mass2", "x2"): "c1.x", ("mass2", "v2"): "c1.v"}


def test_a_force_on_its_own_point_with_a_transformation_factor_minus_one(ssp):
    """force_factor = -1: the bond's force is -f1 = fc, mass2 moves as in the plain pair; libcosim, on the same
    SSP file, applies the transformation and gives the plain pair's answer bit for bit."""
    document, _ = zencosim.manager.scene.imports.import_system(ssp["own"])
    assert document["couplings"]["c1"]["force_factor"] == -1.0
    own = zencosim.run(zencosim.load_scene(ssp["own"]))
    plain = zencosim.run(zencosim.load_scene(ssp["plain"]))
    theirs = run_osp(ssp["own"], END_TIME, [*BOND, ("mass1", "f1")])
    theirs_plain = run_osp(ssp["plain"], END_TIME, list(BOND))
    for key in BOND:
        assert np.array_equal(theirs[key], theirs_plain[key]), key
    assert np.array_equal(theirs[("mass1", "f1")][:2], [-20.0, -29.994])  # the force on mass 1: -fc
    differences = compare(own, theirs, BOND)
    assert max(differences.values()) <= AGREEMENT, differences
    for name in ("c1.x", "c1.v", "c1.f"):  # -1 * (-fc) is fc: exactly the plain pair
        assert np.array_equal(own.signal(name).values, plain.signal(name).values), name


def test_a_position_in_mm_is_converted_at_the_fmus_boundary(ssp):
    """mass2_mm's x2 in mm: zencosim's signal c1.x is in m (converted where mass2 outputs it); libcosim needs
    the conversion written out (factor 0.001) and then agrees; without it, x2_in is 1000 times too large."""
    ours = zencosim.run(zencosim.load_scene(ssp["mm"]))
    theirs = run_osp(ssp["mm_transformed"], END_TIME, [*PAIR])
    differences = compare(ours, theirs, {**BOND, ("mass1", "fc"): "c1.f"}, scale={"c1.x": 1000.0})
    assert max(differences.values()) <= AGREEMENT, differences
    unconverted = run_osp(ssp["mm"], END_TIME, [("mass2", "x2")])
    assert np.max(np.abs(unconverted[("mass2", "x2")])) > 1e100  # libcosim converts no units
    plain = zencosim.run(zencosim.load_scene(ssp["plain"]))
    assert largest_difference(ours.signal("c1.x").values, plain.signal("c1.x").values) <= AGREEMENT
