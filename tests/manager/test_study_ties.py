"""A study's answer does not follow timing noise (issue 25, item 3; docs/study.md, Ties).

One run of a study recommended extrapolation=1 at 20.4 ms of CPU time per simulated second where the documented
run recommended extrapolation=0 at 19 ms, for the same grid: the two costs differ by less than the spread of the
repeats. Settings whose measured cost ranges overlap that of the cheapest are tied; the answer says so and breaks
the tie by a stated rule: fewer exchanges, then lower error, then lower median cost.
"""
from __future__ import annotations

import pytest

from zencosim.manager.study import study
from zencosim.manager.study.report import answer_table, points_table
from zencosim.manager.study.tradeoffs import TIE_RULE, answer, tied_with

TARGET = 0.01
ZOH, FOH = 0, 1  # the two settings of the issue, at one macro-step: as many exchanges each
EXCHANGES = {ZOH: 500.0, FOH: 500.0, 2: 250.0}


def _never(i: int) -> float:
    raise AssertionError(f"exchanges counted for point {i}, which ties with nothing")


def test_costs_within_the_spread_are_tied_and_the_lower_error_breaks_the_tie_whichever_median_is_lower():
    """The issue's two readings: ZOH at 19 ms and FOH at 20.4 ms, or the other way round; each range holds both."""
    ranges = [(0.0182, 0.0221), (0.0185, 0.0215)]
    errors = [0.00126, 0.00087]  # FOH is the more accurate
    stable = [True, True]
    documented = answer([0.0190, 0.0204], ranges, errors, stable, TARGET, EXCHANGES.__getitem__)
    noisy = answer([0.0204, 0.0190], ranges, errors, stable, TARGET, EXCHANGES.__getitem__)
    assert documented == (FOH, [FOH, ZOH])
    assert noisy == (FOH, [FOH, ZOH])  # the same recommendation from both runs


def test_fewer_exchanges_come_before_a_lower_error():
    costs, ranges = [0.0190, 0.0204, 0.0199], [(0.0182, 0.0221), (0.0185, 0.0215), (0.0189, 0.0230)]
    errors = [0.00126, 0.00087, 0.0060]  # point 2: a larger macro-step, half the exchanges, still within 1 %
    best, tied = answer(costs, ranges, errors, [True] * 3, TARGET, EXCHANGES.__getitem__)
    assert best == 2 and tied == [2, FOH, ZOH]


def test_costs_apart_by_more_than_their_spread_are_not_tied():
    costs, ranges = [0.0190, 0.0240], [(0.0185, 0.0199), (0.0231, 0.0262)]
    assert answer(costs, ranges, [0.00126, 0.00087], [True, True], TARGET, _never) == (ZOH, [ZOH])


def test_only_stable_points_meeting_the_target_take_part_in_a_tie():
    costs, ranges = [0.0190, 0.0195, 0.0200], [(0.018, 0.022)] * 3
    errors = [0.00126, 0.02, 0.0005]  # point 1 misses the target, point 2 is unstable
    assert answer(costs, ranges, errors, [True, True, False], TARGET, _never) == (ZOH, [ZOH])
    assert answer(costs, ranges, errors, [False, True, False], TARGET, _never) == (None, [])


def test_one_repeat_has_no_spread_and_ties_only_equal_costs():
    assert tied_with([(0.019, 0.019), (0.0190001, 0.0190001)], [0, 1], 0) == [0]
    assert tied_with([(0.019, 0.019), (0.019, 0.019)], [0, 1], 0) == [0, 1]


def _row(key: str, extrapolation: int, cost: float, low: float, high: float, error: float) -> dict:
    return {"key": key, "method": f"extrapolation={extrapolation}", "macro_step": 0.004,
            "values": {"manager.macro_step": 0.004, "manager.extrapolation": extrapolation}, "stable": True,
            "stable_predicted": True, "stable_run": True, "failed": None, "error": error, "nrms": {"x2": error},
            "energy_error": None, "zenoh": None, "pareto": False, "exchanges_per_s": None, "error_bar": None,
            "inproc": {"loop_cpu_per_s": cost, "loop_cpu_min_per_s": low, "loop_cpu_max_per_s": high,
                       "loop_wall_per_s": 10 * cost}}


def _table(rows: list[dict], targets: tuple[float, ...], exchanges) -> tuple[list[dict], list[str]]:
    answers = [study._answer(rows, target, exchanges) for target in targets]
    return answers, answer_table({"signal": "x2", "points": rows, "answers": answers})


def _cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip("|").split("|")]


@pytest.mark.parametrize("zoh_cost, foh_cost", [(0.0190, 0.0204), (0.0204, 0.0190)])
def test_the_answer_table_lists_the_tied_settings_as_rows_and_states_the_rule(zoh_cost, foh_cost):
    """Issue 42: the answer was one sentence of 600 characters; now a row per target, the chosen setting first, then
    a row per setting tied with it, with its spread and exchanges, and the rule under the table."""
    rows = [_row("zoh", 0, zoh_cost, 0.0182, 0.0221, 0.00126), _row("foh", 1, foh_cost, 0.0185, 0.0215, 0.00087)]
    for row in rows:
        row["exchanges_per_s"] = 500.0  # as the study's counter leaves it on every tied row
    (result,), table = _table(rows, (TARGET,), lambda row: 500.0)
    assert result["point"] == "foh" and result["tied"] == ["foh", "zoh"] and result["tie_rule"] == TIE_RULE
    assert _cells(table[0]) == ["NRMS target", "cheapest setting", "macro-step [ms]",
                                "CPU in process [ms/s] (fastest–slowest)", "wall over Zenoh [ms/s]", "NRMS of x2"]
    assert _cells(table[2]) == ["≤ 1 %", "FOH (chosen, 500 exchanges/s)", "4", f"{foh_cost * 1e3:.3g} (18.5–21.5)",
                                "not measured", "0.00087"]
    assert _cells(table[3]) == ["", "ZOH (tied on cost, 500 exchanges/s)", "4", f"{zoh_cost * 1e3:.3g} (18.2–22.1)",
                                "not measured", "0.00126"]
    assert table[-1] == f"Tied: {TIE_RULE}."
    assert len({len(line) for line in table[:4]}) == 1  # columns padded: read as it is printed


def test_without_a_tie_the_table_has_a_row_per_target_and_says_where_none_meets_it():
    rows = [_row("zoh", 0, 0.0190, 0.0185, 0.0199, 0.00126), _row("foh", 1, 0.0240, 0.0231, 0.0262, 0.00087)]
    rows[1]["zenoh"] = {"loop_wall_per_s": 0.0507}
    rows[1]["error_bar"] = 0.00012  # against an extrapolated reference
    answers, table = _table(rows, (TARGET, 0.001, 0.0001), lambda row: pytest.fail("no tie: nothing to count"))
    assert [(a["point"], a["tied"]) for a in answers] == [("zoh", ["zoh"]), ("foh", ["foh"]), (None, [])]
    assert [_cells(line) for line in table[2:]] == [
        ["≤ 1 %", "ZOH", "4", "19 (18.5–19.9)", "not measured", "0.00126"],
        ["≤ 0.1 %", "FOH", "4", "24 (23.1–26.2)", "50.7", "0.00087 ± 0.00012"],
        ["≤ 0.01 %", "none: no stable point of the grid meets it", "–", "–", "–", "–"]]


def test_the_points_table_shows_each_cost_with_its_spread():
    rows = [_row("zoh", 0, 0.0190, 0.0182, 0.0221, 0.00126), _row("foh", 1, 0.0204, 0.0204, 0.0204, 0.00087)]
    table = "\n".join(points_table({"signal": "x2", "points": rows}))
    assert "| 19 (18.2–22.1) |" in table and "| 20.4 |" in table


def test_against_an_extrapolated_reference_a_point_meets_a_target_only_with_its_error_bar():
    """An NRMS estimated at 0.000995 ± 0.0001 may be above 0.1 % (two_mass_damped_fmu, SOH at 0.5 ms: its analytic
    NRMS is 0.001006): it does not meet it; the dearer point whose bar is inside does."""
    rows = [_row("fine", 2, 0.10, 0.09, 0.11, 0.000995), _row("finer", 2, 0.20, 0.19, 0.21, 0.0008)]
    rows[0]["error_bar"], rows[1]["error_bar"] = 0.0001, 0.0001
    result = study._answer(rows, 0.001, lambda row: pytest.fail("no tie: nothing to count"))
    assert result["point"] == "finer" and result["error_bar"] == 0.0001
    rows[1]["error_bar"] = 0.00021
    assert study._answer(rows, 0.001, lambda row: pytest.fail("no tie"))["point"] is None
