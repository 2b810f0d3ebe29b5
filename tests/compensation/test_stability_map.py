"""Stability maps (paper 003, §3): qualitative claims of the paper, the writers, the name registry."""
from __future__ import annotations

import json

import numpy as np
import pytest

from zencosim.compensation.implicit.stability_map import STABILITY_TOLERANCE, stability_map, write_stability_map

# the four fixed parameter sets (alpha_m21, alpha_lambda_r21, alpha_lambda_i21) that §3.1.1 lists for
# Fig. 9; reading: Figs. 10–15 (figures not in the extracted text) use the same four sets
PAPER_PARAMETER_SETS = [(1.0, 1.0, 1.0), (10.0, 1.0, 1.0), (1.0, 10.0, 1.0), (1.0, 1.0, 10.0)]
ZOOM = {"lambda_r1_range": (-0.3, 0.0), "lambda_i1_range": (0.0, 0.3), "grid_points": 16}  # step 0.02


def _fixed(parameters):
    return dict(zip(("alpha_m21", "alpha_lambda_r21", "alpha_lambda_i21"), parameters))


@pytest.mark.parametrize("parameters", PAPER_PARAMETER_SETS)
def test_projection_displacement_displacement_k0_is_stable_everywhere(parameters):
    """§3.3.1: "For k = 0, we only detect stable points" on [-2, 0] x [0, 2] (17 x 17 points, step
    0.125, including the origin and both axes).

    rho <= 1 + STABILITY_TOLERANCE (1e-6): rho = 1 exactly at the origin (two free masses) up to
    float64 rounding, see ``stability_map``. Observed max rho - 1 is rounding-level (< 1e-14).
    """
    result = stability_map("projection", "displacement-displacement", 0, grid_points=17, **_fixed(parameters))
    assert result.stable.all(), result.spectral_radius.max()


def test_weighted_multiplier_force_force_k2_is_unstable_near_the_origin():
    """§3.1.2 and §5: a = b = 1, k = 2 has an unstable region at the vertical axis, "not stable for
    lambda_r1, lambda_i1 -> 0"; §4 places its edge near lambda_r1 = -0.1.

    On the paper's zoom window [-0.3, 0] x [0, 0.3] with alpha = (1, 1, 1): damped points near the
    origin are unstable by far more than rounding (rho(-0.04, 0.1) = 1.068, observed), the unstable
    points all lie at lambda_r1 > -0.1 and the rest of the window is stable. Baumgarte mu_bar = 1 with
    the same k is stable on the whole window (§3.1.1, §5: "stable results are obtained").
    """
    result = stability_map("weighted-multiplier", "force-force", 2, **ZOOM)
    lambda_r1, _ = np.meshgrid(result.lambda_r1, result.lambda_i1)
    unstable = ~result.stable
    assert unstable[lambda_r1 < -0.01].any()
    assert lambda_r1[unstable].min() > -0.1
    assert result.stable[lambda_r1 <= -0.1].all()
    near_origin = result.spectral_radius[5, 13]  # (lambda_r1, lambda_i1) = (-0.04, 0.1)
    assert (result.lambda_r1[13], result.lambda_i1[5]) == pytest.approx((-0.04, 0.1))
    assert near_origin > 1.0 + 1e3 * STABILITY_TOLERANCE

    baumgarte = stability_map("baumgarte", "force-force", 2, **ZOOM)
    assert baumgarte.stable.all()


def test_write_stability_map_png_and_json(tmp_path):
    result = stability_map("baumgarte", "force-displacement", 1, grid_points=5, method_options={"beta": 0.5, "gamma": 0.0625})
    png_path, json_path = write_stability_map(result, tmp_path / "map.png")
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json_path == tmp_path / "map.json"
    data = json.loads(json_path.read_text())
    assert data["method"] == "baumgarte"
    assert data["method_parameters"] == {"beta": 0.5, "gamma": 0.0625}
    assert (data["decomposition"], data["k"]) == ("force-displacement", 1)
    assert data["lambda_r1"] == pytest.approx(np.linspace(-2.0, 0.0, 5))
    assert data["lambda_i1"] == pytest.approx(np.linspace(0.0, 2.0, 5))
    np.testing.assert_array_equal(data["spectral_radius"], result.spectral_radius)
    np.testing.assert_array_equal(data["stable"], result.stable)


@pytest.mark.parametrize(
    "method, decomposition, message",
    [
        ("baumgarten", "force-force", "unknown coupling method 'baumgarten'; expected one of baumgarte, weighted-multiplier, projection"),
        ("projection", "force/force", "unknown decomposition 'force/force'; expected one of force-force, force-displacement, displacement-displacement"),
        ("baumgarte", "displacement-displacement", "method 'baumgarte' is not defined for the displacement-displacement decomposition"),
    ],
)
def test_bad_names_give_clear_errors(method, decomposition, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        stability_map(method, decomposition, 0, grid_points=2)
