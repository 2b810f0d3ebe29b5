"""The coupling law of paper 003 on a joint with two axes (a point in the plane, the double pendulum of
§4): the conditions hold per axis, so a joint whose axes do not interact is two scalar joints, and
turning the frame turns the answer."""
from __future__ import annotations

import numpy as np
import pytest

from zencosim.compensation.implicit.coupling_laws import Baumgarte, Projection, WeightedMultiplier, corrected_coupling
from zencosim.compensation.implicit.decompositions import DECOMPOSITIONS

METHODS = [Baumgarte(0.3, 0.02), WeightedMultiplier(1.0, 1.0), Projection()]
CASES = [(method, name) for name in DECOMPOSITIONS for method in METHODS
         if name != "displacement-displacement" or isinstance(method, Projection)]
AXES = 2


def _scalar_problem(rng, n_e, k):
    history = rng.normal(size=(k + 1, n_e))
    outputs = rng.normal(size=(2, 4))
    sensitivity = rng.normal(size=(2, 4, n_e))
    return history, outputs, sensitivity


def _on_axes(history, outputs, sensitivity):
    """Two scalar problems (one per axis) as one planar problem; coupling variables variable-major."""
    n_e = history[0].shape[1]
    planar_history = np.stack(history, axis=-1).reshape(len(history[0]), n_e * AXES)
    planar_outputs = np.stack(outputs, axis=-1)  # (2, 4, d)
    planar_sensitivity = np.zeros((2, 4, AXES, n_e * AXES))
    for axis in range(AXES):
        planar_sensitivity[:, :, axis, axis::AXES] = sensitivity[axis]
    return planar_history, planar_outputs, planar_sensitivity


@pytest.mark.parametrize("method, decomposition", CASES, ids=lambda c: getattr(c, "__name__", str(c)))
def test_independent_axes_are_two_scalar_joints(method, decomposition):
    """Tolerance 1e-12 relative: the same arithmetic, up to the order of the linear solve."""
    rng = np.random.default_rng(5)
    n_e = len(DECOMPOSITIONS[decomposition].coupling_variables)
    problems = [_scalar_problem(rng, n_e, k=1) for _ in range(AXES)]
    scalar = np.stack([corrected_coupling(method, decomposition, *p) for p in problems], axis=-1).ravel()
    planar = corrected_coupling(method, decomposition, *_on_axes(*zip(*problems)))
    np.testing.assert_allclose(planar, scalar, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("method, decomposition", CASES, ids=lambda c: getattr(c, "__name__", str(c)))
def test_turning_the_frame_turns_the_coupling_variables(method, decomposition):
    """Every output level and coupling variable is a vector of the plane: in a frame turned by R the
    sensitivities are R S R^T per variable and the answer is R e. Tolerance 1e-12 relative (rounding)."""
    rng = np.random.default_rng(8)
    n_vars = len(DECOMPOSITIONS[decomposition].coupling_variables)
    history = rng.normal(size=(3, n_vars, AXES))  # k = 2
    outputs = rng.normal(size=(2, 4, AXES))
    sensitivity = rng.normal(size=(2, 4, AXES, n_vars, AXES))
    angle = 0.7
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])

    def solve(h, y, s):
        return corrected_coupling(method, decomposition, h.reshape(3, -1), y, s.reshape(2, 4, AXES, -1)).reshape(n_vars, AXES)

    turned = solve(history @ R.T, outputs @ R.T, np.einsum("ia,slajb,kb->slijk", R, sensitivity, R))
    np.testing.assert_allclose(turned, solve(history, outputs, sensitivity) @ R.T, rtol=1e-12, atol=1e-12)
