"""A small linear subsystem's step as straight-line code (``subsystems.straight_line``): the same step as numpy's
products to rounding, its input values at the step's end bit for bit, and on generated linear scenes the direct
path equal to the message path bit for bit (both run the same straight-line steps)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zencosim.manager.assembly import build_subsystems, make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.results.summary import digest
from zencosim.manager.scene.load import load_scene
from zencosim.subsystems import straight_line
from zencosim.subsystems.inputs import InputPolynomial

# every linear subsystem the bundled scenes hold, with a micro-step a quarter of its communication step too
LINEAR = [("two_mass_damped", "S1"), ("two_mass_damped", "S2"), ("four_mass", "S1"), ("mass_chain", "S3"),
          ("multiple_oscillator_n5", "M5"), ("constrained_two_mass", "S1"), ("double_oscillator", "M1")]
STEPS = 300


def _subsystem(scene: str, name: str, micro_steps: int):
    loaded = load_scene(scene)
    micro = loaded.manager.macro_step / micro_steps
    return build_subsystems(load_scene(scene, [f"subsystems.{name}.micro_step={micro!r}"]))[name], \
        loaded.manager.macro_step_ns


@pytest.mark.parametrize("scene, name", LINEAR, ids=[f"{scene}.{name}" for scene, name in LINEAR])
@pytest.mark.parametrize("rows", [1, 2, 3])
@pytest.mark.parametrize("micro_steps", [1, 4])
def test_the_straight_line_step_is_numpys_step_to_rounding(monkeypatch, scene, name, rows, micro_steps):
    straight, span_ns = _subsystem(scene, name, micro_steps)
    products, _ = _subsystem(scene, name, micro_steps)
    rng = np.random.default_rng(11)
    scale = np.abs(np.concatenate(([1.0], straight.z))).max()  # inputs of the size of the state
    ours, theirs, states = [], [], []
    for k in range(STEPS):
        coefficients = rng.normal(scale=scale, size=(rows, len(straight.inputs)))
        ours.append(straight.advance(k * span_ns, (k + 1) * span_ns, InputPolynomial(coefficients)))
        with monkeypatch.context() as patched:  # more products than any step may have: numpy's
            patched.setattr(straight_line, "MAX_TERMS", -1)
            theirs.append(products.advance(k * span_ns, (k + 1) * span_ns, InputPolynomial(coefficients)))
        states.append((straight.z.copy(), products.z.copy()))
        # the input values at the step's end: the same Horner's scheme in the same order, bit for bit
        assert list(straight.w) == InputPolynomial(coefficients).at(span_ns * 1e-9).tolist()
    assert straight._straight and all(step is not None for step in straight._straight.values())
    assert all(step is None for step in products._straight.values())
    # the two sum a row's products in different orders (OpenBLAS may fuse them): a few ulps a step, which the
    # stable step map does not grow; 1e-12 of a signal's largest magnitude over the run is issue 26's bound
    ours, theirs = np.array(ours), np.array(theirs)
    assert (np.abs(ours - theirs).max(axis=0) <= 1e-12 * np.abs(theirs).max(axis=0)).all()
    ours_z, theirs_z = (np.array(side) for side in zip(*states))
    assert np.abs(ours_z - theirs_z).max() <= 1e-12 * np.abs(theirs_z).max()


def test_a_step_with_too_many_products_or_a_non_finite_entry_keeps_numpys():
    Phi, Psi, G = np.ones((2, 2)), np.ones((2, 1)), np.ones((4, 3))
    assert straight_line.straight_line_step(Phi, Psi, 1, 1e-3, G, 1, None) is not None
    assert straight_line.straight_line_step(np.ones((20, 20)), np.ones((20, 1)), 1, 1e-3, np.ones((22, 21)), 1,
                                            None) is None
    Phi[0, 1] = math.inf
    assert straight_line.straight_line_step(Phi, Psi, 1, 1e-3, G, 1, None) is None


@st.composite
def linear_scenes(draw) -> list[str]:
    """Overrides of two_mass_damped: masses, springs, dampers, the coupling, extrapolation and micro-steps, in the
    ranges of paper 000 §5.4 (stable and unstable co-simulations both)."""
    value = st.floats(0.1, 10.0)
    overrides = [f"subsystems.S1.bodies.m1.mass={draw(value)!r}", f"subsystems.S2.bodies.m2.mass={draw(value)!r}",
                 f"subsystems.S1.effects.k1.stiffness={100 * draw(value)!r}",
                 f"subsystems.S2.effects.k2.stiffness={100 * draw(value)!r}",
                 f"subsystems.S1.effects.c1.damping={draw(value)!r}", f"subsystems.S2.effects.c2.damping={draw(value)!r}",
                 f"couplings.c.effects.kc.stiffness={100 * draw(value)!r}",
                 f"couplings.c.effects.cc.damping={draw(value)!r}",
                 f"manager.extrapolation={draw(st.integers(0, 2))}", "manager.duration=0.2"]
    for name in ("S1", "S2"):
        overrides.append(f"subsystems.{name}.micro_step={0.001 / draw(st.sampled_from([1, 2, 5]))!r}")
    return overrides


@settings(max_examples=25, deadline=None)
@given(linear_scenes())
def test_on_generated_linear_scenes_the_direct_path_is_the_message_path_bit_for_bit(overrides):
    records = []
    for direct in (False, True):
        scene = load_scene("two_mass_damped", overrides)
        plan, subsystems = plan_scene(scene)
        scheme = make_scheme(scene, plan, direct=DirectCalls(plan, subsystems) if direct else None)
        with np.errstate(over="ignore", invalid="ignore"):
            records.append(run_in_process(scheme, plan, subsystems))
    through_messages, direct = records
    assert digest(direct) == digest(through_messages)
    for ours, theirs in zip(direct.trajectories, through_messages.trajectories):
        assert np.array_equal(ours, theirs, equal_nan=True)
    assert np.array_equal(direct.residual_energy, through_messages.residual_energy, equal_nan=True)
