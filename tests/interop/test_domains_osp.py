"""Power bonds of other domains against libcosim, the OSP reference engine, on the same OspSystemStructure.xml
(issue 24 item 3, import side).

The peer pair (tests/interop/peer_pair.py: two FMUs compiled here from tests/interop/fmus/peer_mass.c, not
written by or for zencosim) in the units of another domain: the same equations, their modelDescription
declaring an inertia, a stiffness and a damping, and an effort, a flow and a displacement (``mass1_<domain>``,
``mass2_<domain>``). Three systems, one per way OSP declares a bond:

* rotational: OSP-IS ``AngularMechanicalPort`` groups (a ``Torque`` and an ``AngularVelocity``) and an
  ``AngularDisplacement`` group connection; zencosim: a rotational bond exchanging the angle;
* electrical: ``ElectromagneticPort`` groups (a ``Voltage`` and a ``Current``) alone, no charge connected;
  zencosim: an electrical bond with ``displacement = []`` (mass1's charge input x2_in keeps its start value 0
  in both engines: another system than the others, the same in both);
* hydraulic: plain ``VariableConnection`` elements, pressure [Pa] and volume flow [m3/s] marked with one
  ``powerBond`` name (by their units), and the volume [m3]; zencosim: a hydraulic bond.

libcosim copies values and knows no domains; zencosim runs the imported scene (its bond of that domain). The
trajectories agree to rounding alone (libcosim's doStep size t_{k+1} - t_k of rounded time points,
docs/interop.md): within 1e-12 of each signal's largest magnitude. What zencosim refuses and libcosim runs:
a port whose effort is of another domain on one side (a translational FMU's force [N] connected as the
Torque of an AngularMechanicalPort).
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("libcosimpy")
pytest.importorskip("fmpy")

import zencosim  # noqa: E402
from tests.interop.libcosim_oracle import run_osp  # noqa: E402
from tests.interop.measures import AGREEMENT, largest_difference  # noqa: E402
from tests.interop.peer_pair import (  # noqa: E402
    DISPLACEMENT,
    END_TIME,
    MASS1_START,
    MASS2_START,
    PAIR,
    STEPS,
    model_identifier,
    variable_connection,
)
from tests.interop.peer_systems import write_osp  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="building the FMUs needs gcc")

PEER_SIGNALS = {"x2": ("mass2", "x2"), "v2": ("mass2", "v2"), "fc": ("mass1", "fc")}

PORT_GROUPS = {  # domain -> (port, effort group, flow group, displacement group)
    "rotational": ("AngularMechanicalPort", "Torque", "AngularVelocity", "AngularDisplacement"),
    "electrical": ("ElectromagneticPort", "Voltage", "Current", "Charge"),
}


def osp_model_description(domain: str, effort: str, flow: str, displacement: str | None) -> str:
    """An OspModelDescription of one peer FMU: a port ``port`` of its ``effort`` and ``flow`` variables and,
    given one, a displacement group ``position`` of ``displacement``."""
    port, effort_group, flow_group, displacement_group = PORT_GROUPS[domain]
    position = (f'\n    <{displacement_group} name="position"><Variable ref="{displacement}"/></{displacement_group}>'
                if displacement else "")
    return f"""<?xml version="1.0" encoding="utf-8"?>
<OspModelDescription xmlns="https://open-simulation-platform.com/OspModelDescription/1.0.0" version="1.0">
  <VariableGroups>
    <{port} name="port">
      <{effort_group} name="port effort"><Variable ref="{effort}"/></{effort_group}>
      <{flow_group} name="port flow"><Variable ref="{flow}"/></{flow_group}>
    </{port}>{position}
  </VariableGroups>
</OspModelDescription>
"""


def _group_connection(name_1: str, name_2: str) -> str:
    return f"""
    <VariableGroupConnection>
      <VariableGroup simulator="mass1" name="{name_1}"/>
      <VariableGroup simulator="mass2" name="{name_2}"/>
    </VariableGroupConnection>"""


HYDRAULIC_CONNECTIONS = "".join(variable_connection(*ends, bond="line") for ends in PAIR) + DISPLACEMENT


def write_domain_system(directory: Path, domain: str, models: tuple[str, str] | None = None) -> Path:
    """The peer pair in ``domain`` as an OSP system in ``directory`` (see the module text)."""
    mass1, mass2 = models or (f"mass1_{domain}", f"mass2_{domain}")
    if domain == "hydraulic":
        connections = HYDRAULIC_CONNECTIONS
    else:
        displacement = domain == "rotational"
        (directory / f"{model_identifier(mass1)}_OspModelDescription.xml").parent.mkdir(parents=True, exist_ok=True)
        (directory / f"{model_identifier(mass1)}_OspModelDescription.xml").write_text(
            osp_model_description(domain, "fc", "v2_in", "x2_in" if displacement else None))
        (directory / f"{model_identifier(mass2)}_OspModelDescription.xml").write_text(
            osp_model_description(domain, "fc_in", "v2", "x2" if displacement else None))
        connections = _group_connection("port", "port")
        if displacement:
            connections += _group_connection("position", "position")
    return write_osp(directory, {"mass1": (mass1, MASS1_START), "mass2": (mass2, MASS2_START)}, connections,
                     f"the peer pair in {domain} units")


DOMAINS = ("rotational", "electrical", "hydraulic")


@pytest.fixture(scope="module")
def systems(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("peer_domains")
    return {domain: write_domain_system(root / domain, domain) for domain in DOMAINS}


@pytest.fixture(scope="module")
def libcosim_runs(systems) -> dict:
    return {domain: run_osp(path, END_TIME, PEER_SIGNALS.values()) for domain, path in systems.items()}


@pytest.fixture(scope="module")
def zencosim_runs(systems) -> dict:
    runs = {}
    for domain, path in systems.items():
        scene = zencosim.load_scene(path)
        runs[domain] = (scene, zencosim.run(scene))
    return runs


def bond_signals(result, coupling: str, displacement: bool) -> dict[str, np.ndarray]:
    signals = {"v2": result.signal(f"{coupling}.v").values, "fc": result.signal(f"{coupling}.f").values}
    if displacement:
        signals["x2"] = result.signal(f"{coupling}.x").values
    return signals


@pytest.mark.parametrize("domain", DOMAINS)
def test_the_imported_scene_has_a_bond_of_the_domain(systems, domain):
    from zencosim.manager.scene.imports import import_system

    document, _ = import_system(systems[domain])
    ((name, coupling),) = document["couplings"].items()
    assert coupling["type"] == "force_displacement" and coupling["domain"] == domain
    assert name == ("line" if domain == "hydraulic" else "c1")
    assert coupling["displacement"] == ([] if domain == "electrical" else f"{name}.x")
    for table in document["subsystems"].values():
        assert [point["domain"] for point in table["points"].values()] == [domain]


@pytest.mark.parametrize("domain", DOMAINS)
def test_zencosim_gives_libcosims_answer_in_every_domain(libcosim_runs, zencosim_runs, domain):
    scene, result = zencosim_runs[domain]
    (coupling,) = scene.couplings
    theirs = libcosim_runs[domain]
    assert len(theirs.time) == STEPS + 1
    ours = bond_signals(result, coupling, domain != "electrical")
    assert np.allclose(result.signal(f"{coupling}.v").time, theirs.time, rtol=0.0, atol=1e-12)
    for signal, values in ours.items():
        difference = largest_difference(values, theirs[PEER_SIGNALS[signal]])
        assert difference <= AGREEMENT, (signal, difference)


def test_the_domains_with_a_displacement_are_the_translational_pair_in_libcosim(tmp_path, libcosim_runs):
    """The units are the modelDescription's only: the rotational and the hydraulic pair are the translational
    pair's numbers bit for bit in libcosim (the electrical one, without its charge, is another system)."""
    from tests.interop.peer_pair import write_system

    translational = run_osp(write_system(tmp_path / "plain", "plain"), END_TIME, PEER_SIGNALS.values())
    for domain in ("rotational", "hydraulic"):
        for key in PEER_SIGNALS.values():
            assert np.array_equal(libcosim_runs[domain][key], translational[key]), (domain, key)
    assert not np.array_equal(libcosim_runs["electrical"][("mass2", "x2")], translational[("mass2", "x2")])


def test_a_port_of_mixed_domains_runs_in_libcosim_and_zencosim_refuses_it(tmp_path):
    """mass1 (translational: fc in N, v2_in in m/s) connected to mass2_rotational through AngularMechanicalPort
    groups: libcosim copies the values; zencosim refuses the port, naming its torque connection of a force."""
    path = write_domain_system(tmp_path / "mixed", "rotational", models=("mass1", "mass2_rotational"))
    assert len(run_osp(path, 0.01, PEER_SIGNALS.values()).time) == 11
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene(path)
    reasons = [problem.reason for problem in caught.value.problems]
    assert reasons == ["connects variables of different quantities: force, torque",
                       "connects variables of different quantities: angular_velocity, velocity",
                       "connects variables of different quantities: angle, displacement"], reasons
