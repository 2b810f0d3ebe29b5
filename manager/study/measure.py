"""What a study measures at one point: accuracy, stability and cost (docs/study.md has every key).

* accuracy: the run summary's NRMS of every output signal against the scene's reference (paper 000 Eq. 42;
  ``manager.results.summary``) and the energy error at the end, ``(E(t_end) - E_ref(t_end)) / |E(0)|``;
* stability: the exact discrete verdict of ``zencosim analyze`` where the scene is linear and has no energy
  correction (the spectral radius of the runtime's own scheme, compensated or not:
  ``manager.analysis.discrete``), and what the run did (``stable`` of the summary); the point's verdict is
  the first when there is one, else the second. A compensator that cannot be designed for the point
  (``SceneError`` at build time) is an unstable point that did not run;
* cost in process: wall and CPU time per simulated second of a run as ``manager.run.execute`` does it
  (building the subsystems, the compensator's design, the stepping loop) and of its stepping loop alone,
  medians over repeats;
* cost over Zenoh: wall time per simulated second of ``execute`` (subsystem processes started) and of its
  stepping loop, CPU time of the manager and its child processes over the whole run (start-up included),
  the digest (it must equal the in-process one), and the number of exchanges: commands the scheme sent to
  subsystems, each answered by one reply (the same on both buses).
"""
from __future__ import annotations

import os
import resource
import statistics
import time

import numpy as np

from zencosim.manager.analysis.discrete import run_scheme
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import run_in_process
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.results.summary import digest
from zencosim.manager.run import execute, summarize_run
from zencosim.manager.scene.load import Scene, SceneError, load_scene
from zencosim.manager.scheme.base import Exchange, RunRecord, SubsystemFailure
from zencosim.manager.study.extrapolation import Samples


def predicted_stability(scene: Scene) -> tuple[bool | None, float | None]:
    """``zencosim analyze``'s verdict and spectral radius for the scene as it runs (compensated when it asks
    for the compensator, ``run_scheme``); ``(None, None)`` where there is none (not linear, energy correction);
    ``(False, None)`` when the compensator cannot be designed; ``(None, None)`` for an energy-controlled step."""
    if scene.manager.step_control == "energy":  # the analysis is of one fixed macro-step
        return None, None
    try:
        scheme = run_scheme(scene)
    except SceneError:
        return False, None
    return (None, None) if scheme is None else (scheme.stable, scheme.spectral_radius)


def _energy_error(summary: dict) -> float | None:
    """The final energy's error relative to the initial energy; None where there is no reference energy, or a value
    was not finite (the summary writes it as null: a diverged point)."""
    energy = summary["energy"]
    if energy is None or "reference_final" not in energy or not summary["signals"]:
        return None
    final, reference, initial = energy["final"], energy["reference_final"], energy["initial"]
    if final is None or reference is None or not initial:
        return None
    return (final - reference) / abs(initial)


def measure_point(scene_ref: str, overrides: tuple[str, ...], repeats: int, signals_file: str | None = None) -> dict:
    """Accuracy, stability and in-process cost of one point (module docstring); ``signals_file``: where to keep
    every output signal of the run (``save_signals``), for a reference extrapolated from the grid's points."""
    scene = load_scene(scene_ref, list(overrides))
    predicted, radius = predicted_stability(scene)
    row = {"steps": scene.manager.duration_ns // scene.manager.macro_step_ns, "duration": scene.manager.duration,
           "stable_predicted": predicted, "spectral_radius": radius}
    walls, cpus, loop_walls, loop_cpus = [], [], [], []
    try:
        with np.errstate(all="ignore"):  # an unstable point overflows
            for _ in range(repeats):
                wall, cpu = time.perf_counter(), time.process_time()
                plan, subsystems = plan_scene(scene)  # as manager.run.execute runs a scene in process
                scheme = make_scheme(scene, plan)
                loop_wall, loop_cpu = time.perf_counter(), time.process_time()
                record = run_in_process(scheme, plan, subsystems)
                loop_cpus.append(time.process_time() - loop_cpu)
                cpus.append(time.process_time() - cpu)
                loop_walls.append(time.perf_counter() - loop_wall)
                walls.append(time.perf_counter() - wall)
            summary = summarize_run(scene, record, "inproc", loop_walls[-1])
            if signals_file is not None:
                save_signals(scene, record, signals_file)
    except (SceneError, SubsystemFailure) as error:  # the compensator cannot be designed at this step, a model fails
        reason = str(error.problems[0]) if isinstance(error, SceneError) else str(error)
        return {**row, "stable": False, "stable_run": None, "failed": reason, "reference": None,
                "nrms": {}, "energy_error": None, "digest": None, "inproc": None}
    if summary["step_control"] is not None:  # energy-controlled: the macro-steps it took
        row["steps"] = summary["steps"]
    run_verdict = summary["stable"] if summary["stable"] is not None else not summary["diverged"]  # no energy: finite
    return {**row,
            "stable": run_verdict if predicted is None else predicted,
            "stable_run": summary["stable"],
            "failed": None,
            "reference": summary["reference"],
            "nrms": {name: entry.get("nrms") for name, entry in summary["signals"].items()},
            "energy_error": _energy_error(summary),
            "digest": summary["digest"],
            "inproc": {**_per_simulated_second(scene, walls, cpus, loop_walls, loop_cpus), "repeats": repeats}}


def save_signals(scene: Scene, record: RunRecord, path: str) -> None:
    """Every signal of ``outputs.signals`` at its communication points, as ``.npz``: ``names``, and per signal ``i``
    its sample times ``t<i>`` [ns] and values ``y<i>`` (``load_signals``)."""
    arrays = {"names": np.array(scene.outputs.signals, dtype=str)}
    for i, name in enumerate(scene.outputs.signals):
        ratio = record.plan.subsystems[record.plan.signals[name][0]].ratio
        arrays[f"t{i}"] = record.row_ticks(0, record.row_count(ratio), ratio) * record.plan.base_step_ns
        arrays[f"y{i}"] = np.asarray(record.signal(name), dtype=float)
    temporary = f"{path}.{os.getpid()}.tmp.npz"
    np.savez(temporary, **arrays)
    os.replace(temporary, path)


def load_signals(path: str) -> dict[str, Samples] | None:
    """The signals ``save_signals`` kept (None: no such file, or one that does not read)."""
    try:
        with np.load(path) as arrays:
            return {str(name): Samples(arrays[f"t{i}"].astype(np.int64), arrays[f"y{i}"])
                    for i, name in enumerate(arrays["names"])}
    except (OSError, ValueError, KeyError):
        return None


def _per_simulated_second(scene: Scene, walls: list, cpus: list, loop_walls: list, loop_cpus: list) -> dict:
    """Medians of the measured times [s] divided by the simulated duration [s]; the fastest and the slowest
    stepping loop's CPU time too, where it is measured."""
    per_s = 1.0 / scene.manager.duration
    times = {"wall_per_s": statistics.median(walls) * per_s, "cpu_per_s": statistics.median(cpus) * per_s,
             "loop_wall_per_s": statistics.median(loop_walls) * per_s,
             "loop_cpu_per_s": None if loop_cpus is None else statistics.median(loop_cpus) * per_s}
    if loop_cpus is not None:  # the spread of the cost: ties within it are broken by a stated rule (tradeoffs)
        times.update(loop_cpu_min_per_s=min(loop_cpus) * per_s, loop_cpu_max_per_s=max(loop_cpus) * per_s)
    return times


class _CountingTap:
    """A run recorder (``manager.run.RunRecorder``, a ``manager.scheme.replica.Tap``) that only counts the
    commands sent to subsystems."""

    result = None

    def __init__(self) -> None:
        self.sent = 0

    def start(self, *_args) -> None:
        pass

    def exchange(self, replies: dict[str, bytes] | None, request: Exchange | None) -> None:
        if request is not None:
            self.sent += len(request.sends)

    def finish(self, outcome: str) -> dict:
        self.result = {"outcome": outcome}
        return self.result

    def close(self) -> None:
        pass


def count_exchanges(scene: Scene) -> int:
    """Commands the scheme sends to subsystems over the run (an in-process run; the scheme is the same on both
    buses)."""
    counter = _CountingTap()
    with np.errstate(all="ignore"):
        execute(scene, "inproc", recorder=counter)
    return counter.sent


def measure_zenoh(scene_ref: str, overrides: tuple[str, ...], repeats: int) -> dict:
    """Cost of one point over Zenoh (module docstring); run in the study's own process, one point at a time."""
    scene = load_scene(scene_ref, list(overrides))
    walls, loops, cpus, digests = [], [], [], set()
    with np.errstate(all="ignore"):
        for _ in range(repeats):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            wall, cpu = time.perf_counter(), time.process_time()
            record, loop_s = execute(scene, "zenoh", zenoh_options=ZenohOptions())
            walls.append(time.perf_counter() - wall)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(time.process_time() - cpu + (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime))
            loops.append(loop_s)
            digests.add(digest(record))
    exchanges = count_exchanges(scene)
    return {**_per_simulated_second(scene, walls, cpus, loops, None), "repeats": repeats,
            "digest": digests.pop() if len(digests) == 1 else None, "exchanges": exchanges,
            "exchanges_per_s": exchanges / scene.manager.duration}
