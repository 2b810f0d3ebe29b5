"""Results out: every signal with its time and unit, from a run (``run --out``, ``Result.write``) and from
its recording (``export``, ``load_recording``), bit for bit the same."""
from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest

import zencosim

MULTI_RATE = {"manager.macro_step": 1e-4, "subsystems.M1.comm_ratio": 10, "subsystems.M1.micro_step": 1e-4,
              "subsystems.M2.micro_step": 1e-4, "manager.duration": 0.5}  # M1 every 1 ms, M2 every 0.1 ms


def _zencosim(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def _read_csv(path) -> dict[str, np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return {name: np.array([float(row[j]) for row in rows[1:]]) for j, name in enumerate(rows[0])}


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.ascontiguousarray(a, "<f8").tobytes() == np.ascontiguousarray(b, "<f8").tobytes()


@pytest.mark.multiprocess
def test_run_out_csv_holds_the_runs_signals_bit_for_bit_and_export_of_its_recording_the_same_file(tmp_path):
    ran = _zencosim("run", "two_mass_damped", "--quiet", "--out", "out.csv", "--record", "run.mcap", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    exported = _zencosim("export", "run.mcap", "--out", "exported.csv", cwd=tmp_path)
    assert exported.returncode == 0, exported.stderr
    assert (tmp_path / "out.csv").read_bytes() == (tmp_path / "exported.csv").read_bytes()

    table = _read_csv(tmp_path / "out.csv")
    assert list(table) == ["time [s]", "fc [N]", "S1.energy [J]", "x2 [m]", "v2 [m/s]", "S2.energy [J]",
                           "delta_p.c [W]", "delta_e.c [J]"]
    record = zencosim.run(zencosim.load_scene("two_mass_damped")).record
    assert _same_bits(table["x2 [m]"], record.signal("x2"))
    assert _same_bits(table["fc [N]"], record.signal("fc"))
    assert _same_bits(table["delta_e.c [J]"], record.residual_energy[:, 0])
    assert _same_bits(table["time [s]"], np.arange(10001) * 1_000_000 / 1e9)


def test_a_multi_rate_run_gives_one_table_per_communication_step_without_holes(tmp_path):
    scene = zencosim.load_scene("double_oscillator", MULTI_RATE)
    result = zencosim.run(scene, record=tmp_path / "run.mcap")
    written = result.write(tmp_path / "out.csv")
    assert [p.name for p in written] == ["out.100us.csv", "out.1ms.csv"]
    fine, coarse = (_read_csv(p) for p in written)
    assert list(fine) == ["time [s]", "x2 [m]", "v2 [m/s]", "M2.energy [J]"]
    assert list(coarse) == ["time [s]", "f [N]", "M1.energy [J]", "delta_p.c [W]", "delta_e.c [J]"]
    assert _same_bits(fine["time [s]"], np.arange(5001) * 100_000 / 1e9)
    assert _same_bits(coarse["time [s]"], np.arange(501) * 1_000_000 / 1e9)
    assert all(np.isfinite(column).all() for table in (fine, coarse) for column in table.values())
    assert _same_bits(coarse["f [N]"], result.record.signal("f"))
    recorded = zencosim.load_recording(tmp_path / "run.mcap").write(tmp_path / "exported.csv")
    assert [p.read_bytes() for p in recorded] == [p.read_bytes() for p in written]


def test_npz_and_parquet_hold_the_same_columns_as_csv(tmp_path):
    result = zencosim.run(zencosim.load_scene("two_mass_damped", {"manager.duration": 0.5}))
    (csv_path,) = result.write(tmp_path / "out.csv")
    (npz_path,) = result.write(tmp_path / "out.npz")
    (parquet_path,) = result.write(tmp_path / "out.parquet")
    import pyarrow.parquet as pq
    from_csv, from_npz, from_parquet = _read_csv(csv_path), np.load(npz_path), pq.read_table(parquet_path).to_pydict()
    assert list(from_npz.keys()) == list(from_csv) == list(from_parquet)
    for name, column in from_csv.items():
        assert _same_bits(from_npz[name], column) and _same_bits(np.array(from_parquet[name]), column)


def test_a_diverged_implicit_run_and_its_recording_end_at_the_same_committed_step(tmp_path):
    scene = zencosim.load_scene("double_pendulum", {"manager.implicit.method": "weighted-multiplier",
                                                    "manager.extrapolation": 2})
    result = zencosim.run(scene, record=tmp_path / "run.mcap")
    diverged_at_s = result.summary["implicit"]["diverged_at_s"]
    assert diverged_at_s is not None and diverged_at_s < scene.manager.duration
    (table,) = result.tables()
    assert table.columns["time [s]"][-1] == diverged_at_s  # the step that opened the joint, committed
    (recorded,) = zencosim.load_recording(tmp_path / "run.mcap").tables()
    assert list(recorded.columns) == list(table.columns)
    assert all(_same_bits(recorded.columns[name], column) for name, column in table.columns.items())


@pytest.mark.multiprocess
@pytest.mark.parametrize("arguments,reason", [
    (["run", "two_mass_damped", "--record", "started.mcap", "--out", "missing/out.csv"],
     "results file missing/out.csv: the directory missing does not exist"),
    (["run", "two_mass_damped", "--record", "started.mcap", "--out", "out.txt"],
     "results file out.txt: unknown file type '.txt'; expected one of .csv, .npz, .parquet"),
    (["run", "two_mass_damped", "--record", "started.mcap", "--summary", "missing/summary.json"],
     "summary missing/summary.json: the directory missing does not exist"),
    (["run", "two_mass_damped", "--record", "missing/run.mcap"],
     "recording missing/run.mcap: the directory missing does not exist"),
    (["export", "run.mcap", "--out", "missing/out.csv"],
     "results file missing/out.csv: the directory missing does not exist"),
])
def test_an_output_path_that_cannot_be_written_is_refused_before_the_run(tmp_path, arguments, reason):
    result = _zencosim(*arguments, cwd=tmp_path)
    assert result.returncode == 2
    assert reason in " ".join(result.stderr.split()) and "Traceback" not in result.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written, not even the recording: the run did not start


def test_signals_are_named_with_their_units_and_an_unknown_name_lists_the_known_ones():
    result = zencosim.run(zencosim.load_scene("two_mass_damped", {"manager.duration": 0.01}))
    x2 = result.signal("x2")
    assert (x2.unit, x2.source, len(x2.time)) == ("m", "S2", 11)
    assert result.signal("S1.energy").unit == "J" and result.signal("delta_p.c").unit == "W"
    with pytest.raises(KeyError, match="no signal 'x3'; expected one of fc, S1.energy, x2"):
        result.signal("x3")


def test_the_csv_writer_round_trips_extreme_values(tmp_path):
    values = np.array([0.0, -0.0, 5e-324, -1.7976931348623157e308, 0.1 + 0.2, np.nan, np.inf, -np.inf])
    table = zencosim.Table(1_000_000, {"time [s]": np.arange(len(values)) / 1e3, "v [m/s]": values})
    from zencosim.manager.results.tables import write_tables
    (path,) = write_tables([table], tmp_path / "extreme.csv")
    assert _same_bits(_read_csv(path)["v [m/s]"], values)
