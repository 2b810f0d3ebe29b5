"""A long run in bounded memory (manager.scheme.window): its arrays go to spill files as it runs, and the
summary, the digest and the results file read them back in blocks, so a run's peak memory does not grow with
its length. Each run is a fresh process (peak RSS of a process only grows); the figures are
benchmarks/bench_memory.py's.
"""
from __future__ import annotations

import json
import subprocess
import sys
import threading

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import zencosim
import zencosim.manager.results.reference as reference_module
from zencosim.manager.bus.backlog import Backlog
from zencosim.manager.results.reference import (
    SOLVE_IVP_ATOL,
    SOLVE_IVP_METHOD,
    SOLVE_IVP_RTOL,
    CoupledSystem,
    solve_ivp_reference,
)
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.window import BLOCK_ROWS, RowWindow, Spill, read_rows, row_blocks

# two_mass_damped at 1 ms: before the arrays were bounded a run held ~0.45 kB per macro-step, so 10 s -> 200 s
# grew the peak by ~85 MB. Bounded, what a run holds does not depend on its length once it is longer than a
# block (8192 steps, so both runs here are): a few windows of 8 200 rows and the blocks being read back
# (~1 MB together). The bound leaves room for the allocator's noise between two processes and is still 17x
# below the growth it replaces.
GROWTH_BOUND_KB = 5 * 1024
# Over Zenoh the manager also buffers what its idle-priority replica has not taken yet (up to 1 MB of batches,
# then disk), and once those batches pass 3 KiB Zenoh maps its shared-memory pool (16 MiB, zenoh's default) in
# the manager and the sending subsystem: measured on an idle machine 100.6 -> 120.0 -> 119.5 MB (manager) at
# 10, 200 and 1 000 s simulated, RssShmem 0 -> 16-17 MB (docs/memory.md). The bound catches growth with run
# length, not that one-time pool.
ZENOH_MANAGER_GROWTH_BOUND_KB = 40 * 1024

CHILD = """
import json, resource, sys, tempfile
import zencosim
scene = zencosim.load_scene("two_mass_damped", {"manager.duration": float(sys.argv[1])})
result = zencosim.run(scene, sys.argv[2], keep=False)
with tempfile.TemporaryDirectory() as folder:
    result.write(folder + "/out.csv")
print(json.dumps({"self_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "children_kb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
                  "digest": result.digest, "stable": result.summary["stable"]}))
"""


def _peak_rss(duration_s: float, bus: str) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, str(duration_s), bus], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("written", [3 * BLOCK_ROWS + 5, 100])  # every row; a run that stopped early
def test_a_spilled_window_gives_the_array_written_and_reads_columns_from_its_file(written):
    rows, history = 3 * BLOCK_ROWS + 5, 4
    values = np.random.default_rng(15).normal(size=(rows, 3))
    expected = np.full((rows, 3), np.nan)
    expected[:written] = values[:written]
    window = RowWindow(rows, 3, float, np.nan, history, Spill(), "test")
    for row in range(written):
        window.put(row, values[row])
        assert np.array_equal(window.row(max(row - history + 1, 0)), values[max(row - history + 1, 0)])
    spilled = window.finish()
    assert isinstance(spilled, np.memmap) and spilled.tobytes() == expected.tobytes()
    column = spilled[::3, 1]  # a view: read from the file, not through the mapping
    assert read_rows(column, 5, 2000).tobytes() == expected[::3, 1][5:2000].tobytes()
    assert np.concatenate([block for _, block in row_blocks(column)]).tobytes() == expected[::3, 1].tobytes()


def test_the_backlog_of_a_lagging_manager_replica_keeps_order_and_spills_beyond_its_memory_bound():
    backlog = Backlog(memory_bytes=1000)
    sent = [(f"S{i % 3}", bytes([i % 251]) * (10 + i)) for i in range(300)]  # ~48 kB: most go to the file
    producer = threading.Thread(target=lambda: [backlog.put(item) for item in (*sent, None)])
    producer.start()
    taken = []
    while (item := backlog.get()) is not None:
        taken.append(item)
        assert backlog._held <= 1000
    producer.join()
    assert taken == sent and backlog._file is not None


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(1800)
def test_peak_memory_of_a_200_s_run_is_that_of_a_10_s_run_on_both_buses_with_one_digest():
    runs = {(bus, duration): _peak_rss(duration, bus) for bus in ("inproc", "zenoh") for duration in (10.0, 200.0)}
    short, long = runs["inproc", 10.0], runs["inproc", 200.0]
    assert short["stable"] and long["stable"]
    assert long["self_kb"] - short["self_kb"] < GROWTH_BOUND_KB, (short, long)
    short, long = runs["zenoh", 10.0], runs["zenoh", 200.0]
    assert long["self_kb"] - short["self_kb"] < ZENOH_MANAGER_GROWTH_BOUND_KB, (short, long)
    for duration in (10.0, 200.0):  # spilled on both buses, and bit-identical
        assert runs["inproc", duration]["digest"] == runs["zenoh", duration]["digest"]


@pytest.mark.parametrize("scene, overrides", [
    ("two_mass_damped", {"manager.duration": 20.0}),
    ("double_oscillator", {"manager.duration": 12.0, "manager.correction.enabled": True, "manager.correction.mu": 0.5}),
    # the implicit scheme; its solve_ivp reference is integrated block by block when spilled (checked below)
    ("constrained_two_mass", {"manager.duration": 9.0, "outputs.reference": "none"}),
])
def test_a_spilled_run_gives_the_kept_runs_arrays_digest_and_summary(scene, overrides, tmp_path):
    # longer than a block: the spilled run writes blocks to its files and reads them back in several blocks
    loaded = zencosim.load_scene(scene, overrides)
    assert loaded.manager.duration_ns // loaded.manager.macro_step_ns > BLOCK_ROWS
    kept, spilled = zencosim.run(loaded, keep=True), zencosim.run(loaded, keep=False)
    assert isinstance(spilled.record.trajectories[0], np.memmap) and not isinstance(kept.record.trajectories[0],
                                                                                   np.memmap)
    for a, b in zip(kept.record.trajectories, spilled.record.trajectories):
        assert a.tobytes() == b.tobytes()
    assert kept.record.residual_energy.tobytes() == spilled.record.residual_energy.tobytes()
    for log, spilled_log in zip(kept.record.corrections, spilled.record.corrections):
        assert log.force.tobytes() == spilled_log.force.tobytes() and log.work.tobytes() == spilled_log.work.tobytes()
    # the summary read in blocks: equal up to the rounding of sums over blocks instead of numpy's pairwise sums
    # (1e-9 relative is far above that and far below any figure's meaning); the wall-clock timing differs anyway
    for key in set(kept.summary) - {"timing"}:
        _assert_close(kept.summary[key], spilled.summary[key], key)
    kept_files, spilled_files = kept.write(tmp_path / "kept.csv"), spilled.write(tmp_path / "spilled.csv")
    assert [p.read_bytes() for p in kept_files] == [p.read_bytes() for p in spilled_files]


@pytest.mark.parametrize("block_rows", [BLOCK_ROWS, 7])
def test_a_spilled_solve_ivp_reference_is_the_kept_one_and_both_are_scipys_solve_ivp_sampling(block_rows, monkeypatch):
    """The solve_ivp reference integrates in one pass and writes the samples of each solver step as it is taken: a
    long run's, spilled to files, is the kept one's bit for bit, and both are what scipy's ``solve_ivp`` gives at
    its ``t_eval`` (the oracle; the outputs evaluated as the reference evaluates them, at every 97th tick): bit for
    bit where no solver step spans more than a block of samples (``BLOCK_ROWS``), else within a few units of the
    last place (a step's dense output evaluated a block at a time rounds as numpy's product of that size does;
    blocks of 7 here, so that each step's samples span several)."""
    monkeypatch.setattr(reference_module, "BLOCK_ROWS", block_rows)
    scene = load_scene("two_mass_damped", ["manager.macro_step=1e-4", "manager.duration=1.0",
                                           "subsystems.S1.micro_step=1e-4", "subsystems.S2.micro_step=1e-4"])
    n_ticks, step = scene.manager.duration_ns // scene.manager.macro_step_ns, scene.manager.macro_step_ns * 1e-9
    kept, spilled = solve_ivp_reference(scene), solve_ivp_reference(scene, spill=Spill())
    assert isinstance(spilled.energy, np.memmap) and not isinstance(kept.energy, np.memmap)
    assert np.asarray(spilled.energy).tobytes() == kept.energy.tobytes()
    for name, signal in kept.signals.items():
        assert np.asarray(spilled.signals[name]).tobytes() == signal.tobytes(), name
    system = CoupledSystem(scene)
    solution = solve_ivp(system.derivative, (0.0, n_ticks * step), system.z0, method=SOLVE_IVP_METHOD,
                         t_eval=np.arange(n_ticks + 1) * step, rtol=SOLVE_IVP_RTOL, atol=SOLVE_IVP_ATOL,
                         first_step=step)
    assert solution.nfev < n_ticks // 7  # the solver's steps span many ticks
    ticks = range(0, n_ticks + 1, 97)
    ours = np.array([[kept.signals[name][tick] for name in system.plan.signals] for tick in ticks])
    scipys = np.array([[y[sub][j] for sub, j in system.plan.signals.values()]
                       for y in (system.outputs(solution.t[tick], solution.y[:, tick]) for tick in ticks)])
    if block_rows == BLOCK_ROWS:
        assert ours.tobytes() == scipys.tobytes()
    else:
        scale = np.max(np.abs(scipys), axis=0)  # a signal's size: values near its zero crossings round with it
        assert (np.abs(ours - scipys) <= 4 * np.finfo(float).eps * scale).all()


def _assert_close(a, b, where: str) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            _assert_close(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-300, nan_ok=True), where
    else:
        assert a == b, where
