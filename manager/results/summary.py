"""The run summary: accuracy against the references, energy, residual energy, stability, timing, digest.

Definitions (docs/summary.md lists every key):

* NRMS (paper 000 Eq. 42): ``sqrt(mean_k (x_k - x_ref,k)^2) / (max x_ref - min x_ref)`` over the
  signal's communication points. Reading taken: Eq. 42's ``/T`` is the number of samples (a root
  mean square), not the duration in seconds, which would make the error depend on the units of time.
* diverged: a recorded value is not finite, or an implicit run diverged (``zencosim run`` then exits 3).
* stable: for a linear scene without energy correction, the exact discrete verdict of ``zencosim analyze``
  (spectral radius of the scheme the run executes, compensated or not, ρ <= 1: ``manager.analysis``); for
  any other scene, the run did not diverge and the mechanical energy does not grow exponentially: the
  least-squares slope of ``ln`` of the windowed energy maximum (20 windows over the run) over the second
  half of the run is below ``STABLE_GROWTH_RATE`` (energy doubling time above 69 s; meant for free or
  bounded-forcing runs). Without energy (no subsystem reports one, no output in J) no verdict: null, unless the
  run diverged (false). ``stable_from`` says which; the measured slope is reported where there is an energy.
* strict JSON: every number that is not finite is null, and ``non_finite`` maps its dotted key to what it
  was (``NaN``, ``Infinity``, ``-Infinity``).
* digest: sha256 over every subsystem's output trajectory (scene order of subsystems, declared
  order of outputs, each as float64 little-endian over its communication points). Equal digests
  mean bit-identical runs.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
from typing import Iterator

import numpy as np

from zencosim.compensation.implicit.coupling_laws import method_name
from zencosim.manager.analysis.discrete import run_scheme
from zencosim.manager.bus.timing import run_timing
from zencosim.manager.results.monitor import residual_power_spikes
from zencosim.manager.results.reference import Reference
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.scheme.energy_step import abs_tolerance, initial_energy, step_bounds
from zencosim.manager.scheme.implicit import compile_joint
from zencosim.manager.scheme.window import BLOCK_ROWS, read_rows, row_blocks

STABLE_GROWTH_RATE = 0.01  # [1/s]
ENERGY_WINDOWS = 20
AT_LIMIT_SHARE = 0.5  # a step that sat at a bound for more than this share of the run is reported (``at_limit``)


def nrms(x: np.ndarray, x_ref: np.ndarray) -> float:
    """Normalised root-mean-square error of ``x`` against ``x_ref`` (paper 000 Eq. 42, reading above)."""
    span = float(np.max(x_ref) - np.min(x_ref))
    return float(np.sqrt(np.mean((x - x_ref) ** 2)) / span)


def streamed_nrms(x: np.ndarray, x_ref: np.ndarray) -> float:
    """:func:`nrms` of ``x`` against ``x_ref`` sampled where ``x`` is (``reference_samples``), both read in blocks
    (``manager.scheme.window.row_blocks``): the sums of one pass, so a long run's arrays need not be in memory.
    Equal to ``nrms(x, x_ref)`` for arrays in memory (one block), and up to the rounding of the sums for a
    spilled run's."""
    squares, count, high, low = 0.0, 0, -math.inf, math.inf
    for first, values in row_blocks(x):
        reference = read_rows(x_ref, first, first + len(values))
        squares += float(np.sum((values - reference) ** 2))
        count += len(values)
        high, low = max(high, float(np.max(reference))), min(low, float(np.min(reference)))
    return float(np.sqrt(squares / count) / (high - low))


def reference_samples(x_ref: np.ndarray, record: RunRecord, ratio: int) -> np.ndarray:
    """A reference (a sample every base step) where a subsystem of ``ratio`` has its samples: every ``ratio``-th,
    or, in an energy-controlled run, at every ``ratio``-th of its points (read whole: a point per macro-step)."""
    if record.point_ticks is None:
        return x_ref[::ratio]
    return np.asarray(x_ref)[np.asarray(record.point_ticks[::ratio])]


def digest(record: RunRecord) -> str:
    """sha256 of every output trajectory (module text), each column read in blocks."""
    h = hashlib.sha256()
    for trajectory in record.trajectories:
        for j in range(trajectory.shape[1]):
            for _, values in row_blocks(trajectory[:, j]):
                h.update(np.ascontiguousarray(values, dtype="<f8").tobytes())
    return h.hexdigest()


def energy_outputs(plan) -> list[tuple[int, int]]:
    """``(subsystem, output)`` of each energy the balance sums: the subsystems' declared energies; where none
    declares one, each subsystem's only output in J (a model's output the scene publishes as a signal)."""
    declared = [(s.index, s.energy_output) for s in plan.subsystems if s.energy_output is not None]
    if declared:
        return declared
    joules = [(s.index, [j for j, port in enumerate(s.outputs) if port.unit == "J"]) for s in plan.subsystems]
    return [(index, found[0]) for index, found in joules if len(found) == 1]


def energy_blocks(record: RunRecord) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """``(first sample, times [s], total mechanical energy [J])`` in blocks, at the points where every subsystem
    has a sample: the sum of the ``energy_outputs`` (nothing when there is none)."""
    subs = record.plan.subsystems
    period = math.lcm(*(s.ratio for s in subs))
    reporting = energy_outputs(record.plan)
    if not reporting:
        return
    columns = [record.trajectories[index][::period // subs[index].ratio, output] for index, output in reporting]
    samples = record.row_count(period)
    for first in range(0, samples, BLOCK_ROWS):
        stop = min(first + BLOCK_ROWS, samples)
        ticks = record.row_ticks(first, stop, period)
        yield first, ticks * record.plan.base_step_ns * 1e-9, sum(read_rows(c, first, stop) for c in columns)


def total_energy(record: RunRecord) -> tuple[np.ndarray, np.ndarray | None]:
    """Times [s] and total mechanical energy [J] where every subsystem has a sample (``energy_blocks``, whole;
    None when there is no energy to sum)."""
    blocks = list(energy_blocks(record))
    if not blocks:
        period = math.lcm(*(s.ratio for s in record.plan.subsystems))
        return record.row_ticks(0, record.row_count(period), period) * record.plan.base_step_ns * 1e-9, None
    return np.concatenate([t for _, t, _ in blocks]), np.concatenate([e for _, _, e in blocks])


def energy_growth_rate(t: np.ndarray, energy: np.ndarray) -> float:
    """Exponential growth rate [1/s] of the energy envelope over the second half of the run (0 for a run of
    fewer than four energy samples, too short to show growth)."""
    envelope = EnergyEnvelope(len(t))
    envelope.add(0, t, energy)
    return envelope.growth_rate()


class EnergyEnvelope:
    """The energy's maximum magnitude in each of ``ENERGY_WINDOWS`` windows over ``samples`` samples (the split
    of ``np.array_split``), filled block by block, and the growth rate it shows (``energy_growth_rate``)."""

    def __init__(self, samples: int) -> None:
        n_windows = min(ENERGY_WINDOWS, samples)
        sizes = [samples // n_windows + (w < samples % n_windows) for w in range(n_windows)]
        self.bounds = np.cumsum([0] + sizes)
        self.peaks = np.zeros(n_windows)
        self.time_sums = np.zeros(n_windows)
        self.sizes = np.array(sizes, dtype=float)

    def add(self, first: int, t: np.ndarray, energy: np.ndarray) -> None:
        window = np.searchsorted(self.bounds, np.arange(first, first + len(t)), side="right") - 1
        np.maximum.at(self.peaks, window, np.abs(energy))
        np.add.at(self.time_sums, window, t)

    def growth_rate(self) -> float:
        n_windows = len(self.peaks)
        if n_windows < 4:
            return 0.0
        centres = self.time_sums / self.sizes
        late = slice(n_windows // 2, None)
        logs = np.log(np.maximum(self.peaks[late], np.finfo(float).tiny))
        return float(np.polyfit(centres[late], logs, 1)[0])


def signal_accuracy(scene: Scene, record: RunRecord, references: dict[str, Reference], reference: Reference | None,
                    finite: bool) -> dict:
    """Per signal of ``outputs.signals``: its subsystem and unit, and its NRMS against ``reference`` (and the
    monolithic run's, when there is one)."""
    signals = {}
    for name in scene.outputs.signals:
        sub_index, output = record.plan.signals[name]
        sub = record.plan.subsystems[sub_index]
        entry = {"subsystem": sub.name, "unit": sub.outputs[output].unit}
        if reference is not None:
            ref = reference.signals[name]
            ref = reference_samples(ref, record, sub.ratio)
            entry["nrms"] = streamed_nrms(record.signal(name), ref) if finite else None
            if "monolithic" in references:
                entry["nrms_monolithic"] = streamed_nrms(
                    reference_samples(references["monolithic"].signals[name], record, sub.ratio), ref)
        signals[name] = entry
    return signals


def energy_balance(record: RunRecord, reference: Reference | None, finite: bool) -> dict | None:
    """The ``energy`` entry of the summary; None when there is no energy to sum (``energy_outputs``).
    ``subsystems`` names the ones summed, when some are not (an FMU without an energy variable); ``outputs`` the
    outputs in J summed, when no subsystem declares its energy."""
    period = math.lcm(*(s.ratio for s in record.plan.subsystems))
    envelope = EnergyEnvelope(record.row_count(period))
    e0 = final = None
    highest, drift = -math.inf, 0.0
    for first, t, energy in energy_blocks(record):
        if e0 is None:
            e0 = float(energy[0])
        final = float(energy[-1])
        highest = float(np.max((highest, np.max(energy))))  # NaN once a value is
        if finite:
            drift = max(drift, float(np.max(np.abs(energy - e0))))
            envelope.add(first, t, energy)
    if e0 is None:
        return None
    balance = {
        "initial": e0, "final": final, "max": highest,
        "max_relative_drift": drift / e0 if e0 > 0 and finite else None,
        "growth_rate_per_s": envelope.growth_rate() if finite else math.inf,
    }
    if reference is not None:
        balance["reference_final"] = float(reference.energy[-1])
    subs = record.plan.subsystems
    reporting = energy_outputs(record.plan)
    if len(reporting) < len(subs):
        balance["subsystems"] = [subs[index].name for index, _ in reporting]
    if all(subs[index].energy_output is None for index, _ in reporting):
        balance["outputs"] = [f"{subs[index].name}.{subs[index].outputs[output].name}" for index, output in reporting]
    return balance


def last_finite(values: np.ndarray) -> float:
    """The last finite value of a 1-D array (read in blocks; NaN where none is)."""
    last = math.nan
    for _, block in row_blocks(values):
        finite = block[np.isfinite(block)]
        if len(finite):
            last = float(finite[-1])
    return last


def summarize(scene: Scene, record: RunRecord, bus: str, wall_s: float, references: dict[str, Reference],
              reference_note: str | None = None, recording: dict | None = None) -> dict:
    plan = record.plan
    diverged_at_s = first_non_finite_time(record)
    finite = diverged_at_s is None and (record.implicit is None or record.implicit.diverged_at is None)
    reference = references.get("analytic") or references.get("solve_ivp")  # what the NRMS is measured against
    signals = signal_accuracy(scene, record, references, reference, finite)
    energy_summary = energy_balance(record, reference, finite)
    timing = run_timing(record, wall_s)
    summary = {
        "scene": scene.name,
        "bus": bus,
        "macro_step": scene.manager.macro_step,
        "duration": scene.manager.duration,
        "steps": record.row_count() - 1,  # the macro-steps taken
        "extrapolation": scene.manager.extrapolation,
        "reference": None if reference is None else reference.kind,
        "subsystems": {s.name: {"comm_step": s.ratio * scene.manager.macro_step,
                                "micro_step": scene.subsystems[s.name].settings.micro_step,
                                "integrator": scene.subsystems[s.name].settings.integrator, "extrapolation": s.order}
                       for s in plan.subsystems},
        "effects": [f"{s.name}.{e}" for s in plan.subsystems for e in s.effects],
        "stable": measured_verdict(energy_summary, finite),
        "signals": signals,
        "energy": energy_summary,
        "residual_energy": {bond.name: last_finite(record.residual_energy[:, b]) for b, bond in enumerate(plan.bonds)},
        "timing": timing,
        "digest": digest(record),
        "overrides": list(scene.overrides),
        "dropped_messages": record.dropped_messages or {},  # over Zenoh: per key (manager.bus.dropped)
    }
    summary["step_control"] = step_control_summary(scene, record)
    discrete = discrete_verdict(scene) if record.point_ticks is None else None  # the analysis is of one macro-step
    summary["discrete"] = discrete
    if discrete is not None:  # a run that overflowed (initial values near 1e308) is not stable whatever ρ is
        summary["stable"] = discrete["stable"] and finite
    summary["stable_from"] = ("exact discrete spectral radius" if discrete is not None else
                              "measured energy growth" if energy_summary is not None else
                              None if finite else "outputs not finite")
    summary["diverged"] = not finite
    summary["diverged_at_s"] = diverged_at_s
    spikes = residual_power_spikes(record, scene.manager.spikes)
    summary["residual_power_spikes"] = {bond: [i.as_dict() for i in found] for bond, found in spikes.items()}
    summary["reliable"] = (False if summary["diverged"] or summary["stable"] is False or any(spikes.values()) else
                           summary["stable"])  # None: no verdict on the stability
    summary["correction"] = correction_summary(scene, record)
    if energy_summary is None:
        summary["energy_candidates"] = energy_candidates(scene)
    if record.implicit is not None:
        summary["implicit"] = implicit_summary(scene, record)
    if scene.replaced_units:
        summary["replaced_units"] = scene.replaced_units
    if reference_note:
        summary["reference_note"] = reference_note
    if recording is not None:
        summary["recording"] = recording  # the recorder's end record (recordings.writer)
    non_finite: dict[str, str] = {}
    summary = finite_or_null(summary, "", non_finite)
    summary["non_finite"] = non_finite
    return summary


def energy_candidates(scene: Scene) -> list[str]:
    """``subsystem.output``: each external model's only output declared in J, which its scene could name as its
    energy (``subsystems.<name>.energy``) where no subsystem reports one."""
    found = []
    for name, sub in scene.subsystems.items():
        description = getattr(sub.spec, "description", None)
        if description is None:
            continue
        joules = [v.name for v in description.variables.values() if v.causality == "output" and v.unit == "J"]
        if len(joules) == 1:
            found.append(f"{name}.{joules[0]}")
    return found


def measured_verdict(energy_summary: dict | None, finite: bool) -> bool | None:
    """``stable`` from the run alone: finite and the energy's growth rate below ``STABLE_GROWTH_RATE``; without an
    energy (``energy_summary`` None) no verdict (None) unless the run diverged (False)."""
    if not finite:
        return False
    if energy_summary is None:
        return None
    return bool(energy_summary["growth_rate_per_s"] < STABLE_GROWTH_RATE)


def step_control_summary(scene: Scene, record: RunRecord) -> dict | None:
    """An energy-controlled run's macro-steps (``manager.scheme.energy_step``): how many, the shortest, longest and
    mean [s], the parameters of the law as it ran (the scene's defaults filled in), the share of the run's time the
    step sat at its smallest and at its largest size, and ``at_limit``, the bound it sat at for more than
    ``AT_LIMIT_SHARE`` of the run ("min_step_size", "max_step_size" or None); None for a run at a fixed macro-step."""
    if record.point_ticks is None:
        return None
    plan = record.plan
    control = scene.manager.energy_control
    ticks = np.asarray(record.point_ticks)
    steps_ns = np.diff(ticks) * plan.base_step_ns
    low, first, high = step_bounds(control, plan.base_step_ns)
    energy = initial_energy(plan, [read_rows(trajectory, 0, 1)[0] for trajectory in record.trajectories])
    parameters = {**dataclasses.asdict(control), "min_step_size": low * 1e-9, "step_size": first * 1e-9,
                  "max_step_size": high * 1e-9, "abs_tolerance": abs_tolerance(control, energy)}
    run_ns = float(steps_ns.sum())
    shares = {"min_step_size": float(steps_ns[steps_ns <= low].sum()) / run_ns,
              "max_step_size": float(steps_ns[steps_ns >= high].sum()) / run_ns}
    at_limit = max(shares, key=shares.get)
    steps = steps_ns * 1e-9
    return {"kind": "energy", "macro_steps": len(steps), "min_step": float(steps.min()), "max_step": float(steps.max()),
            "mean_step": float(steps.mean()), "time_at_min_step": shares["min_step_size"],
            "time_at_max_step": shares["max_step_size"],
            "at_limit": at_limit if shares[at_limit] > AT_LIMIT_SHARE else None, "parameters": parameters}


def first_non_finite_time(record: RunRecord) -> float | None:
    """The first time [s] at which a subsystem's output was not finite (None: every output stayed finite); each
    trajectory read in blocks (``manager.scheme.window.row_blocks``: a long run's spilled array is read from its
    file, not through its mapping, so none of it stays resident)."""
    times = []
    for sub, trajectory in zip(record.plan.subsystems, record.trajectories):
        for first, rows in row_blocks(trajectory):
            bad = np.flatnonzero(~np.isfinite(rows).all(axis=1))
            if bad.size:
                row = int(first + bad[0])
                times.append(int(record.row_ticks(row, row + 1, sub.ratio)[0]) * record.plan.base_step_ns * 1e-9)
                break
    return min(times, default=None)


def discrete_verdict(scene: Scene) -> dict | None:
    """``zencosim analyze``'s verdict on the scheme this scene runs: ``spectral_radius`` ρ, ``growth_rate_per_s``
    ``2 ln ρ / T``, ``stable`` (ρ <= 1) and the predicted growth's time scale, ``energy_doubling_time_s``
    ``ln 2 / growth_rate_per_s`` (None where stable: ρ <= 1 up to round-off); None when the scene is not linear or corrects energy."""
    try:
        scheme = run_scheme(scene)
    except (ValueError, ArithmeticError):  # a transition matrix that cannot be built or decomposed (singular)
        return None
    if scheme is None:
        return None
    growth = scheme.growth_rate
    return {"spectral_radius": scheme.spectral_radius, "growth_rate_per_s": growth, "stable": scheme.stable,
            "energy_doubling_time_s": None if scheme.stable else math.log(2.0) / growth}


def finite_or_null(value, key: str, non_finite: dict[str, str]):
    """``value`` with every float that is not finite replaced by None, its dotted key and what it was recorded
    in ``non_finite`` (JSON has no NaN or infinity: ``json.dumps`` would write tokens no other parser reads)."""
    if isinstance(value, float) and not math.isfinite(value):
        non_finite[key] = "NaN" if math.isnan(value) else "Infinity" if value > 0 else "-Infinity"
        return None
    if isinstance(value, dict):
        return {k: finite_or_null(v, f"{key}.{k}" if key else str(k), non_finite) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_null(v, f"{key}[{i}]", non_finite) for i, v in enumerate(value)]
    return value


def correction_summary(scene, record: RunRecord) -> dict | None:
    """The energy correction's settings and, per corrected point, the work W it injected, the energy error Σ ζ it
    was meant to cancel (paper 002 Eq. 13, summed) and ``adds_energy_error``: W went past −Σ ζ so far, or the
    wrong way, that the net |Σ ζ + W| is larger than |Σ ζ|, the error without the correction (None: no
    correction)."""
    if not record.corrections:
        return None
    settings = scene.manager.correction
    groups = {}
    for log in record.corrections:
        max_force = max(float(np.linalg.norm(force, axis=1).max()) for _, force in row_blocks(log.force))
        work = last_finite(log.work)
        groups[log.name] = {"subsystem": log.subsystem, "mu": dict(zip(log.bonds, log.mu)),
                            "work_injected": work, "energy_error": log.energy_error,
                            "adds_energy_error": bool(abs(log.energy_error + work) > abs(log.energy_error)),
                            "uncorrected_energy": last_finite(log.uncorrected_energy),
                            "max_force": max_force, "capped_steps": log.capped_steps,
                            "withheld_steps": log.withheld_steps, "steps": log.steps}
    return {"mu": settings.mu, "nu": settings.nu, "cap_fraction": settings.cap_fraction, "cap_force": settings.cap_force,
            "work_injected": sum(g["work_injected"] for g in groups.values()), "points": groups}


def implicit_summary(scene: Scene, record: RunRecord) -> dict:
    """The ``implicit`` entry of the run summary (docs/summary.md)."""
    joint = compile_joint(scene, record.plan)
    diverged = record.implicit.diverged_at
    runs = record.implicit.corrector_runs[:diverged] if diverged is not None else record.implicit.corrector_runs
    counts = np.zeros(0, dtype=np.int64)  # macro-steps by corrector runs
    for _, block in row_blocks(runs):
        found = np.bincount(block)
        counts = np.pad(counts, (0, max(0, len(found) - len(counts))))
        counts[:len(found)] += found
    max_gap = np.full(2, -np.inf)  # position, velocity
    path_1, path_2 = (record.trajectories[joint.sides[side]] for side in (0, 1))
    for first, rows_1 in row_blocks(path_1):
        rows_2 = read_rows(path_2, first, first + len(rows_1))
        gaps = np.abs(rows_2[:, joint.outputs[1]] - rows_1[:, joint.outputs[0]])[:, :2]  # (ticks, position/velocity, axes)
        finite = np.isfinite(gaps).all(axis=(1, 2))
        if finite.any():
            max_gap = np.maximum(max_gap, gaps[finite].max(axis=(0, 2)))
    done = int(counts.sum())
    return {
        "method": method_name(joint.method),
        "parameters": dataclasses.asdict(joint.method),
        "decomposition": joint.decomposition.name,
        "k": joint.k,
        "corrector_runs": {"mean": float(np.arange(len(counts)) @ counts / done) if done else None,
                           "max": int(np.flatnonzero(counts)[-1]) if done else 0,
                           "histogram": {int(n): int(c) for n, c in enumerate(counts) if c}},
        "diverged_at_s": None if diverged is None else (diverged + 1) * record.plan.base_step_ns * 1e-9,
        "max_gap": {"position": float(max_gap[0]), "velocity": float(max_gap[1])},
    }
