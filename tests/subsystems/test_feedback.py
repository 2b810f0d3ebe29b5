"""Compensation feedback terms in a masses model: added mass, non-symmetric stiffness and damping,
relayed forces, and the physical energy left alone."""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.subsystems.effects import PlacedEffect, Spring
from zencosim.subsystems.effects.feedback import Feedback
from zencosim.subsystems.models.masses import Body, MassesModel, MassesSpec
from zencosim.subsystems.ports import Attachments, EffectForceOutput, RelayedForce, Terminal

M1, M2, K1, KC = 2.0, 3.0, 50.0, 100.0  # [kg], [kg], [N/m], [N/m]
TERMINAL = Terminal("far", ("x*",), ("v*",))


def _model(*feedback: tuple[str, Feedback, tuple[str, str]], relayed: tuple[str, ...] = ()) -> MassesModel:
    """Two bodies, a spring to the ground on m1 and a coupling spring from m1 to a terminal."""
    spec = MassesSpec({"m1": Body(M1), "m2": Body(M2)}, (PlacedEffect("k1", Spring(K1), ("m1", None)),))
    attached = Attachments(terminals=(TERMINAL,), force_outputs=(EffectForceOutput(("fc",), "m1", ("kc",)),),
                           effects=(("kc", Spring(KC), ("m1", "far")),) + feedback,
                           relayed_forces=(RelayedForce("fc", "far", relayed, -1.0),) if relayed else ())
    return MassesModel(spec, attached)


def test_feedback_acts_on_its_target_only_with_acceleration_as_added_mass():
    gains = Feedback(acceleration_gain=0.5, velocity_gain=0.2, displacement_gain=7.0)
    model = _model(("u", gains, ("m1", "m2")))
    z, w = np.array([0.1, -0.2, 0.3, 0.4]), np.array([0.05, -0.6])  # [x1, x2, v1, v2], [x*, v*]
    a = model.acceleration(0.0, z, w)
    # m1 a1 = -k1 x1 - kc (x1 - x*) - (0.5 a2 + 0.2 v2 + 7 x2);  m2 a2 = 0 (no force on m2, no reaction)
    assert a[1] == 0.0
    assert a[0] == pytest.approx((-K1 * 0.1 - KC * (0.1 - 0.05) - (0.2 * 0.4 + 7.0 * -0.2)) / M1, rel=1e-15)
    # with a2 != 0 the acceleration gain matters: the same term from m1 on itself is an added mass
    own = _model(("u", Feedback(0.5, 0.0, 0.0), ("m1", "m1")))
    assert own.acceleration(0.0, z, w)[0] == pytest.approx((-K1 * 0.1 - KC * (0.1 - 0.05)) / (M1 + 0.5), rel=1e-15)


def test_feedback_from_a_terminal_reads_its_inputs_and_refuses_its_acceleration():
    model = _model(("u", Feedback(0.0, 0.2, 7.0), ("m1", "far")))
    z, w = np.zeros(4), np.array([0.05, -0.6])
    assert model.acceleration(0.0, z, w)[0] == pytest.approx((KC * 0.05 - (0.2 * -0.6 + 7.0 * 0.05)) / M1)
    with pytest.raises(ValueError, match="expected the acceleration of a body of this subsystem"):
        _model(("u", Feedback(0.1, 0.0, 0.0), ("m1", "far")))


def test_a_relayed_term_joins_the_force_output_divided_by_the_receivers_sign():
    # u = -(0.5 a1 + 0.2 v1 + 7 x1) on the remote body, which applies -fc*: fc~ = fc - u
    gains = Feedback(0.5, 0.2, 7.0)
    model = _model(("u21", gains, ("far", "m1")), relayed=("u21",))
    plain = _model()
    z, w = np.array([0.1, -0.2, 0.3, 0.4]), np.array([0.05, -0.6])
    a1 = plain.acceleration(0.0, z, w)[0]  # the relayed term does not act on this subsystem
    assert model.acceleration(0.0, z, w) == pytest.approx(plain.acceleration(0.0, z, w), rel=1e-15)
    u = -(0.5 * a1 + 0.2 * 0.3 + 7.0 * 0.1)
    fc, fc_relayed = plain.outputs_at(0.0, z, w)[0], model.outputs_at(0.0, z, w)[0]
    assert fc_relayed == pytest.approx(fc - u, rel=1e-14)
    assert model.outputs[0].feedthrough  # through fc and through a1
    # the reported energy is the physical one
    assert model.outputs_at(0.0, z, w)[-1] == plain.outputs_at(0.0, z, w)[-1]


def test_an_acceleration_gain_that_removes_all_inertia_is_refused():
    with pytest.raises(ValueError, match="effective mass M \\+ D_fb is singular"):
        _model(("u", Feedback(-M1, 0.0, 0.0), ("m1", "m1")))
