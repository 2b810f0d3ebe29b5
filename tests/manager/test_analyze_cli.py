"""``zencosim analyze``: tables, JSON keys (docs/compensation.md), pole map, and exit status 2 on bad input."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from tests.manager.test_cli import zencosim
from tests.manager.test_compensation import FOUR_MS
from zencosim.cli.main import main


def test_analyze_writes_the_documented_json_and_a_pole_map(tmp_path):
    out, png = tmp_path / "a.json", tmp_path / "poles.png"
    result = zencosim("analyze", "two_mass_damped", *(a for o in FOUR_MS for a in ("--set", o)),
                      "--json", str(out), "--plot", str(png))
    assert result.returncode == 0, result.stderr
    report = json.loads(out.read_text())
    for key in ("monolithic", "cosim_pade", "cosim", "cosim_discrete", "compensated_model", "compensated"):
        poles = report["poles"][key]
        assert len(poles) == 4 and all(len(pair) == 2 for pair in poles)  # [re, im] per pole
    radius = report["spectral_radius"]
    assert radius["uncompensated"] > 1.0 > radius["compensated"]  # paper 000 §5.2.3: unstable at 4 ms
    assert report["stable"] == {"uncompensated": False, "compensated": True}
    assert (report["assignability"]["rank_L"], report["assignability"]["rank_Ln"]) == (8, 8)
    assert [len(report["gains"][kind]) for kind in "dfg"] == [4, 4, 4] and report["gains"]["d"][1] == 0.0
    assert np.array(report["poles"]["compensated"]) == pytest.approx(np.array(report["poles"]["monolithic"]), abs=1e-6)
    assert report["dof_names"] == ["S1.m1", "S2.m2"] and len(report["mode_shapes"]["compensated"][0]) == 2
    assert set(report["modal"]["cosim_discrete"]) == {"omega_n", "xi", "e_omega_percent", "e_xi"}
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for text in ("λ3,4", "UNSTABLE", "rank L / rank [L n]", "discrete correction"):
        assert text in result.stdout


def test_a_scene_without_a_compensator_is_still_analysed(tmp_path):
    out = tmp_path / "a.json"
    result = zencosim("analyze", "multiple_oscillator_n3", "--json", str(out))
    assert result.returncode == 0, result.stderr
    report = json.loads(out.read_text())
    assert report["poles"]["compensated"] is None and report["spectral_radius"]["compensated"] is None
    assert report["stable"]["uncompensated"] is False
    assert "exactly one force_displacement coupling" in report["not_compensated"]


def test_an_unassignable_architecture_exits_2_with_the_ranks():
    result = zencosim("analyze", "two_mass_damped", "--architecture", "rank_one")
    assert result.returncode == 2
    assert "rank L = 4, rank [L n] = 5" in result.stderr


def test_a_nonlinear_scene_exits_2(capsys):
    assert main(["analyze", "nonlinear_oscillator_case1"]) == 2
    assert "expected a linear scene for the analysis: nonlinear effects M1.k1" in capsys.readouterr().err


def test_its_tables_are_whole_when_piped():
    """Written to a pipe (a log file, CI), a table is as wide as it needs, not cut at rich's 80 columns: every
    pole pair's row holds all seven columns on one line."""
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    result = subprocess.run([sys.executable, "-m", "zencosim", "analyze", "two_mass_damped"], capture_output=True,
                            text=True, env=env, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    assert "…" not in result.stdout
    header = next(line for line in result.stdout.splitlines() if "monolithic" in line)
    assert "co-sim. discrete" in header and "compensated discrete" in header
    rows = [line for line in result.stdout.splitlines() if line.startswith("│ λ [1/s]")]
    assert rows and all(line.count("j") == 6 for line in rows)  # six complex poles on one line
