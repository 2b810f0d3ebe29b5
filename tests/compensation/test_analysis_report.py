"""Analysis.to_dict: the JSON shape a CLI can print."""
from __future__ import annotations

import json

import numpy as np
import pytest

from zencosim.compensation.eigenstructure.analysis import analyze
from zencosim.compensation.eigenstructure.architecture import full_feedback, rank_one
from zencosim.compensation.eigenstructure.interface import InterfaceModel


def test_assignable_architecture_report(two_mass):
    model = two_mass(0.1, 4e-3)
    report = json.loads(json.dumps(analyze(model, InterfaceModel(0, 4e-3), 6, full_feedback(model)).to_dict()))
    monolithic = np.array(report["poles"]["monolithic"])
    assert monolithic.shape == (4, 2)
    for key in ("cosim_pade", "cosim", "compensated"):
        assert np.array(report["poles"][key]).shape == (4, 2)
    assert np.array(report["poles"]["compensated"]) == pytest.approx(monolithic, abs=1e-10)
    assert report["poles"]["cosim"][2][0] > 0  # λ3 unstable without compensation at 4 ms
    assert report["assignability"]["rank_L"] == report["assignability"]["rank_Ln"] == 8
    assert [len(report["gains"][kind]) for kind in "dfg"] == [4, 4, 4]
    assert report["gains"]["margin_met"] is True
    assert max(re for re, _ in report["latent"]["compensated_pade"]) <= -report["gains"]["margin"]
    assert report["interface"] == {
        "extrapolation": "ZOH",
        "macro_step": 4e-3,
        "send_delay": 0.0,
        "receive_delay": 0.0,
        "pade_order": 6,
    }


def test_unassignable_architecture_report(two_mass):
    model = two_mass(0.1, 1e-3)
    report = analyze(model, InterfaceModel(0, 1e-3), 6, rank_one(model)).to_dict()
    assert report["assignability"] == {
        "architecture": "rank_one",
        "rank_L": 4,
        "rank_Ln": 5,
        "assignable": False,
        "rtol": 1e-8,
    }
    assert report["gains"] is None and report["poles"]["compensated"] is None
    json.dumps(report)


def test_report_without_architecture(four_mass):
    report = analyze(four_mass(), InterfaceModel(1, 3e-3)).to_dict()
    assert report["assignability"] is None and report["gains"] is None
    assert len(report["poles"]["cosim"]) == 8 and report["interface"]["extrapolation"] == "FOH"
    json.dumps(report)
