"""Power bonds of every physical domain (subsystems.ports.DOMAINS): the same equations written in the quantities of
another domain run as the mechanical bond does — every trajectory, residual power and energy, and paper 002's energy
correction bit for bit — and a bond whose quantities do not fit its domain is refused naming the variable.

The models are the example oscillator (zencosim.examples.oscillator: a mass, a spring and a damper to ground, a
coupling spring–damper) with the units of a rotating inertia on a torsional spring, a fluid inertance on a hydraulic
compliance, and an inductor on a capacitor: two_mass_damped in each domain."""
from __future__ import annotations

import numpy as np
import pytest

import zencosim
from zencosim.examples.oscillator import Oscillator
from zencosim.manager.scene.load import scene_from_text

# domain -> units of (displacement, flow, its derivative, effort, 1/inertia)
UNITS = {
    "translational": ("m", "m/s", "m/s2", "N", "1/kg"),
    "rotational": ("rad", "rad/s", "rad/s2", "N.m", "1/kg.m2"),
    "hydraulic": ("m3", "m3/s", "m3/s2", "Pa", "m3/Pa.s2"),  # volume, volume flow, pressure; 1/inertance
    "electrical": ("C", "A", "A/s", "V", "A/V.s"),  # charge, current, voltage; 1/inductance
}


def _in(domain: str) -> type:
    q, f, a, e, inverse = UNITS[domain]
    return type(f"{domain.capitalize()}Oscillator", (Oscillator,), {
        "__module__": __name__,
        "inputs": {"x_in": q, "v_in": f, "f_in": e},
        "outputs": {"x": q, "v": f, "a": a, "fc": e, "inverse_mass": inverse, "E": "J"}})


TranslationalOscillator, RotationalOscillator, HydraulicOscillator, ElectricalOscillator = map(_in, UNITS)


def scene_text(domain: str, model_domain: str | None = None) -> str:
    model = f"{__name__}:{(model_domain or domain).capitalize()}Oscillator"
    return f"""
name = "two_mass_damped_{domain}"
[manager]
duration = 2.0
macro_step = 0.001
extrapolation = 1
[manager.correction]
enabled = true
[outputs]
signals = ["x2", "fc"]
reference = "none"
[subsystems.S1]
model = "{model}"
micro_step = 0.001
start = {{ m = 1.0, k = 10.0, c = 0.1, kc = 100.0, cc = 0.1, v0 = 100.0 }}
energy = "E"
points.m1 = {{ domain = "{domain}", force = "fc", position_input = "x_in", velocity_input = "v_in" }}
[subsystems.S2]
model = "{model}"
micro_step = 0.001
start = {{ m = 1.0, k = 1000.0, c = 0.1, v0 = -100.0 }}
energy = "E"
points.m2 = {{ domain = "{domain}", force_input = "f_in", position = "x", velocity = "v" }}
[couplings.c]
type = "force_displacement"
domain = "{domain}"
force_side = "S1.m1"
motion_side = "S2.m2"
force = "fc"
displacement = "x2"
velocity = "v2"
"""


def run(domain: str, bus: str = "inproc"):
    return zencosim.run(scene_from_text(scene_text(domain), f"{domain}.toml"), bus=bus)


@pytest.fixture(scope="module")
def translational():
    return run("translational")


@pytest.mark.parametrize("domain", ["rotational", "hydraulic", "electrical"])
def test_a_bond_of_another_domain_runs_as_the_mechanical_one_bit_for_bit(translational, domain):
    result = run(domain)
    ports = {name: result.signal(name) for name in result.signals}
    assert ports["fc"].unit == {"rotational": "N.m", "hydraulic": "Pa", "electrical": "V"}[domain]
    for name, signal in translational.signals.items():  # outputs, then delta_p.c [W] and delta_e.c [J]
        assert ports[name].values.tobytes() == signal.values.tobytes(), name
    (mechanical,), (other,) = translational.record.corrections, result.record.corrections
    assert other.steps == mechanical.steps > 1000 and other.force.tobytes() == mechanical.force.tobytes()
    assert other.work.tobytes() == mechanical.work.tobytes()
    residual = result.signal("delta_e.c").values
    assert np.isfinite(residual).all() and np.abs(residual).max() > 0.0  # the interface does make residual energy


@pytest.mark.multiprocess
def test_a_rotational_bond_gives_one_digest_on_both_buses(tmp_path):
    path = tmp_path / "rotational.toml"  # each subsystem process loads the scene from its file
    path.write_text(scene_text("rotational"))
    assert zencosim.run(str(path)).digest == zencosim.run(str(path), bus="zenoh").digest


def test_a_point_whose_variables_are_not_of_its_domain_is_refused_naming_them():
    with pytest.raises(zencosim.SceneError) as caught:
        scene_from_text(scene_text("rotational", model_domain="translational"), "wrong.toml")
    reasons = {p.key: p.reason for p in caught.value.problems}
    assert reasons["subsystems.S1.points.m1.force"] == "fc is in [N] (kg m s-2); expected [N.m] (torque)"
    assert "subsystems.S2.points.m2.position" in reasons


def test_a_bond_between_points_of_two_domains_is_refused():
    text = scene_text("rotational").replace('points.m2 = { domain = "rotational"', 'points.m2 = { domain = "hydraulic"')
    head, s2 = text.split("[subsystems.S2]")
    text = head + "[subsystems.S2]" + s2.replace("RotationalOscillator", "HydraulicOscillator", 1)
    with pytest.raises(zencosim.SceneError) as caught:
        scene_from_text(text, "mixed.toml")
    assert ("couplings.c.motion_side", "S2: points.m2 is hydraulic (its domain key); the coupling is rotational") in \
        [(p.key, p.reason) for p in caught.value.problems]


def test_a_builtin_model_takes_translational_bonds_only():
    with pytest.raises(zencosim.SceneError) as caught:
        zencosim.load_scene("two_mass_damped", {"couplings.c.domain": "rotational"})
    assert [(p.key, p.reason) for p in caught.value.problems] == [
        ("couplings.c.domain", "model masses of S1 is translational; a rotational bond joins FMUs or Python models"),
        ("couplings.c.domain", "model masses of S2 is translational; a rotational bond joins FMUs or Python models")]
