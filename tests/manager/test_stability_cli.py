"""``zencosim stability``: the spectral-radius map of paper 003 §3 as a PNG and as JSON."""
from __future__ import annotations

import json

import numpy as np

from tests.manager.test_cli import zencosim


def test_stability_writes_the_map_and_its_numbers(tmp_path):
    """The §3.1.2 zoom of the weighted multiplier (a = b = 1, force/force, k = 2): unstable next to the
    imaginary axis, stable left of lambda_r1 = -0.1 (tests/compensation/test_stability_map.py)."""
    result = zencosim("stability", "--method", "weighted-multiplier", "--decomposition", "force-force", "--k", "2",
                      "--grid", "7", "--lambda-r1", "-0.3", "0", "--lambda-i1", "0", "0.3", "--out", str(tmp_path / "m.png"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "m.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads((tmp_path / "m.json").read_text())
    assert (data["method"], data["method_parameters"], data["decomposition"], data["k"]) == (
        "weighted-multiplier", {"a": 1.0, "b": 1.0}, "force-force", 2)
    stable, lambda_r1 = np.array(data["stable"]), np.array(data["lambda_r1"])
    assert not stable[:, lambda_r1 > -0.06].any() and stable[:, lambda_r1 < -0.1].all()
    assert "stable (rho <= 1) at" in result.stdout


def test_baumgarte_options_are_dimensionless_and_json_can_go_elsewhere(tmp_path):
    result = zencosim("stability", "--method", "baumgarte", "--mu-bar", "0.25", "--index", "2", "--decomposition",
                      "force-displacement", "--k", "0", "--grid", "3", "--out", str(tmp_path / "b.png"),
                      "--json", str(tmp_path / "numbers.json"))
    assert result.returncode == 0, result.stderr
    assert json.loads((tmp_path / "numbers.json").read_text())["method_parameters"] == {"beta": 0.5, "gamma": 0.0}


def test_stability_refuses_what_the_paper_does_not_define(tmp_path):
    result = zencosim("stability", "--method", "baumgarte", "--decomposition", "displacement-displacement", "--k", "0",
                      "--out", str(tmp_path / "x.png"))
    assert result.returncode == 2
    assert "method 'baumgarte' is not defined for the displacement-displacement decomposition" in result.stderr
    result = zencosim("stability", "--method", "projection", "--a", "2", "--decomposition", "force-force", "--k", "0",
                      "--out", str(tmp_path / "x.png"))
    assert result.returncode == 2 and "not options of the projection method: --a" in result.stderr
    assert not (tmp_path / "x.png").exists()
