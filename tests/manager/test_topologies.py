"""Topology by output: a chain runs (each force output feeds through only from the next mass's motion, a
state), a star runs, a real algebraic loop is refused naming the outputs on it, and a loop through feedthrough
no component declares is initialised by libcosim's passes."""
from __future__ import annotations

import dataclasses

import pytest

import zencosim
from tests.conftest import REPO
from zencosim.manager.plan.run_plan import Feed, SubsystemPlan, _init_rounds
from zencosim.scenes.topologies import mass_chain, mass_star
from zencosim.subsystems.params import Problems
from zencosim.subsystems.ports import Port

LOOPING_MODEL = '''
import numpy as np

class Soft:
    """A mass whose reported position leads by the applied force: x_out = x + f / k_out (feedthrough)."""
    inputs = {"f": "N"}
    outputs = {"x": "m", "v": "m/s"}
    feedthrough = {"x": ("f",)}
    parameters = {"m": 1.0, "k_out": 1000.0}
    second_order = True

    def __init__(self, m, k_out):
        self.m, self.k_out = m, k_out

    def initial_state(self):
        return np.array([0.0, 0.0])

    def acceleration(self, t, z, u):
        return np.array([u[0] / self.m])

    def outputs_at(self, t, z, u):
        return np.array([z[0] + u[0] / self.k_out, z[1]])
'''


def test_the_bundled_chain_is_the_generated_one():
    assert (REPO / "scenes" / "mass_chain.toml").read_text() == mass_chain(5)


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_chain_of_five_runs_on_both_buses_with_one_digest():
    scene = zencosim.load_scene("mass_chain", {"manager.duration": 1.0})
    inproc = zencosim.run(scene)
    assert inproc.summary["stable"] and inproc.summary["signals"]["x5"]["nrms"] < 0.05  # against the analytic solution
    assert zencosim.run(scene, "zenoh").digest == inproc.digest


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(300)
@pytest.mark.parametrize("kind", ["chain", "star"])
def test_nine_subsystems_over_zenoh_give_the_in_process_digest(tmp_path, kind):
    # nine processes and the manager on two cores: each process follows only its sources (a chain's middle
    # mass two neighbours, the star's hub all eight), and the run is bit-identical to the in-process one
    path = tmp_path / f"{kind}9.toml"
    path.write_text((mass_chain if kind == "chain" else mass_star)(9, duration=0.2))
    inproc = zencosim.run(path)
    zenoh = zencosim.run(path, "zenoh")
    assert zenoh.digest == inproc.digest
    received = {name: report["replies_received"] for name, report in zenoh.summary["timing"]["subsystems"].items()}
    steps = inproc.record.plan.n_ticks
    sources = {name: len(zenoh.record.plan.sources(zenoh.record.plan.by_name(name).index)) for name in received}
    for name, count in received.items():  # each process took only its sources' replies (one per step each)
        assert count <= (steps + 2) * sources[name], (name, count, sources[name])


def test_chains_and_stars_initialise_in_two_rounds_whatever_their_size(tmp_path):
    for n in (2, 3, 9):
        for kind, text in (("chain", mass_chain(n, duration=0.01)), ("star", mass_star(n, duration=0.01))):
            path = tmp_path / f"{kind}{n}.toml"
            path.write_text(text)
            result = zencosim.run(path)
            assert len(result.record.plan.init_rounds) == 2, (kind, n)  # motion outputs, then the forces
            assert result.summary["stable"]


def test_a_real_algebraic_loop_is_refused_naming_its_outputs(tmp_path, monkeypatch):
    (tmp_path / "soft_mass.py").write_text(LOOPING_MODEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    scene = tmp_path / "loop.toml"
    scene.write_text('''
name = "loop"
[manager]
duration = 0.01
macro_step = 0.001
[outputs]
reference = "none"
[subsystems.S1]
model = "masses"
micro_step = 0.001
bodies.m1 = { mass = 1.0 }
[subsystems.S2]
model = "soft_mass:Soft"
micro_step = 0.001
points.p = { force_input = "f", position = "x", velocity = "v" }
[couplings.c]
type = "force_displacement"
force_side = "S1.m1"
motion_side = "S2.p"
force = "fc"
displacement = "x2"
velocity = "v2"
effects.kc = { type = "spring", stiffness = 100.0 }
''')
    with pytest.raises(zencosim.SceneError, match=r"couplings: outputs with direct feedthrough form an algebraic loop: "
                                                  r"S1\.fc <- S2\.x2 <- S1\.fc; an explicit scheme cannot initialise"):
        zencosim.run(scene)


def _ring(names: str, undeclared: str) -> list:
    """Subsystems ``names`` in a ring of signals (each output feeds the next one's input), each output feeding
    through from its input: declared, or only by FMI's default where the name is in ``undeclared``."""
    n = len(names)
    return [SubsystemPlan(i, name, 1, (Port(f"{name}_in", "signal", signal_unit="1"),),
                          (Port(f"{name}_out", "signal", True, "1", None, undeclared=name in undeclared),),
                          (Feed((i - 1) % n, (0,), (0,), 0),), (), 0) for i, name in enumerate(names)]


@pytest.mark.parametrize("undeclared", ["A", "ABC"])
def test_a_loop_through_undeclared_feedthrough_takes_libcosims_n_plus_1_passes(undeclared):
    """One undeclared output breaks the ring as all of them do: every subsystem asked N + 1 = 4 times, the first
    time with no input (no source has answered), then with every input."""
    problems = Problems()
    rounds = _init_rounds(_ring("ABC", undeclared), problems, {})
    assert not problems
    assert [[(step.subsystem, step.ready) for step in round_] for round_ in rounds] == (
        [[(0, ()), (1, ()), (2, ())]] + 3 * [[(0, (0,)), (1, (0,)), (2, (0,))]])


def test_a_loop_of_declared_feedthrough_is_refused_beside_an_undeclared_one():
    declared, undeclared = _ring("AB", ""), _ring("CD", "CD")
    problems = Problems()
    _init_rounds(declared + [dataclasses.replace(s, index=s.index + 2, feeds=(dataclasses.replace(
        s.feeds[0], source=s.feeds[0].source + 2),)) for s in undeclared], problems, {0: "as subsystems.A.feedthrough states it"})
    assert [(p.key, p.reason) for p in problems] == [
        ("couplings", "outputs with direct feedthrough form an algebraic loop: A.A_out <- B.B_out <- A.A_out "
                      "(feedthrough: A's as subsystems.A.feedthrough states it); an explicit scheme cannot initialise them")]
