"""zencosim realtime-probe: every rate of the ladder paced and reported, the verdicts follow the budget.

The figures themselves depend on the machine and its load (benchmarks/bench_realtime.py measures
them); what is checked holds on a busy machine: each rate runs its steps, the shares and verdicts are
the budget applied to the reported numbers, the answer is the highest rate with every lower one meeting.
"""
import json

from hypothesis import given
from hypothesis import strategies as st

from tests.manager.test_cli import zencosim
from zencosim.manager.realtime_probe import RateResult, highest_rate


def test_the_probe_paces_every_rate_and_applies_the_budget_to_what_it_measured(tmp_path):
    report_path = tmp_path / "probe.json"
    result = zencosim("realtime-probe", "two_mass_damped", "--rates", "100,250,300", "--duration", "0.2",
                      "--json", str(report_path), "--every-rate")
    assert result.returncode == 0, result.stderr
    report = json.loads(report_path.read_text())
    assert set(report) == {"scene", "overrides", "bus", "duration_s", "budget", "rates", "highest_rate_hz"}
    assert all(entry["skipped"] is None for entry in report["rates"])  # --every-rate
    by_rate = {entry["rate_hz"]: entry for entry in report["rates"]}
    assert sorted(by_rate) == [100.0, 250.0, 300.0]
    # 300 Hz: a 3.33… ms step, not a whole number of nanoseconds (nor divided by the 1 ms micro-step); reported
    # with the scene's reason, not run
    assert by_rate[300.0]["steps"] is None and "macro_step" in by_rate[300.0]["error"]
    for rate in (100.0, 250.0):
        entry = by_rate[rate]
        assert entry["error"] is None and entry["steps"] == round(0.2 * rate)
        assert entry["missed_share"] == entry["missed_deadlines"] / entry["steps"]
        assert entry["meets"] == (entry["missed_share"] <= 0.01
                                  and entry["lateness_us_p99"] <= 0.3 * entry["macro_step_s"] * 1e6)
        assert 0 <= entry["lateness_us_median"] <= entry["lateness_us_p99"] <= entry["lateness_us_max"]
    assert report["highest_rate_hz"] == highest_rate([RateResult(**{**e, "adjusted": ()}) for e in report["rates"]])
    assert "highest rate within the budget" in result.stdout or "no rate of the ladder" in result.stdout


def test_a_budget_every_run_keeps_gives_the_highest_rate_and_a_short_micro_step_is_shortened(tmp_path):
    report_path = tmp_path / "probe.json"
    result = zencosim("realtime-probe", "two_mass_damped", "--rates", "500,2000", "--duration", "0.1",
                      "--missed", "1", "--p99", "1e9", "--json", str(report_path), "--quiet")
    assert result.returncode == 0, result.stderr
    report = json.loads(report_path.read_text())
    assert report["highest_rate_hz"] == 2000.0
    fast = report["rates"][1]
    assert fast["steps"] == 200 and fast["adjusted"] == ["subsystems.S1.micro_step=0.0005",
                                                          "subsystems.S2.micro_step=0.0005"]


def test_bad_probe_arguments_exit_2():
    assert zencosim("realtime-probe", "two_mass_damped", "--rates", "fast").returncode == 2
    assert zencosim("realtime-probe", "two_mass_damped", "--rates", "100,-5").returncode == 2
    assert zencosim("realtime-probe", "two_mass_damped", "--missed", "2").returncode == 2


def test_the_ladder_stops_at_the_first_rate_that_misses_the_budget(tmp_path):
    """A budget no run keeps (p99 lateness below 0 µs): 100 Hz runs and misses, the higher rates are not run and
    say why; --every-rate runs them all."""
    for every, run in (((), [100.0]), (("--every-rate",), [100.0, 250.0, 500.0])):
        report_path = tmp_path / "probe.json"
        result = zencosim("realtime-probe", "two_mass_damped", "--rates", "100,250,500", "--duration", "0.2",
                          "--p99", "1e-12", "--missed", "0", "--json", str(report_path), *every)
        assert result.returncode == 0, result.stderr
        report = json.loads(report_path.read_text())
        assert [e["rate_hz"] for e in report["rates"] if e["steps"] is not None] == run
        assert report["highest_rate_hz"] is None
        if not every:
            assert all(e["skipped"] == "100 Hz already missed the budget" for e in report["rates"][1:])
            assert "not run: 100 Hz already missed the budget" in result.stdout


@given(st.lists(st.tuples(st.integers(1, 50), st.booleans(), st.booleans()), max_size=8, unique_by=lambda t: t[0]))
def test_the_highest_rate_is_the_top_of_the_run_of_rates_that_meet_from_the_bottom(entries):
    results = [RateResult(rate * 100.0, 1 / (rate * 100.0), meets=meets, error="refused" if refused else None)
               for rate, meets, refused in entries]
    ran = sorted((r for r in results if r.error is None), key=lambda r: r.rate_hz)
    best = highest_rate(results)
    below = [r for r in ran if best is not None and r.rate_hz <= best]
    above = [r for r in ran if best is None or r.rate_hz > best]
    assert all(r.meets for r in below)  # every rate up to the answer meets the budget
    assert not above or not above[0].meets  # and the next one that ran does not (or none ran above)
    assert best is None or best in {r.rate_hz for r in ran}  # refused rates are never the answer
