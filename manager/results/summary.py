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
  bounded-forcing runs). ``stable_from`` says which; the measured slope is reported in both cases.
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

import numpy as np

from zencosim.compensation.implicit.coupling_laws import method_name
from zencosim.manager.bus.timing import run_timing
from zencosim.manager.results.monitor import residual_power_spikes
from zencosim.manager.results.reference import Reference
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.scheme.implicit import compile_joint

STABLE_GROWTH_RATE = 0.01  # [1/s]
ENERGY_WINDOWS = 20


def nrms(x: np.ndarray, x_ref: np.ndarray) -> float:
    """Normalised root-mean-square error of ``x`` against ``x_ref`` (paper 000 Eq. 42, reading above)."""
    span = float(np.max(x_ref) - np.min(x_ref))
    return float(np.sqrt(np.mean((x - x_ref) ** 2)) / span)


def digest(record: RunRecord) -> str:
    h = hashlib.sha256()
    for trajectory in record.trajectories:
        for j in range(trajectory.shape[1]):
            h.update(np.ascontiguousarray(trajectory[:, j], dtype="<f8").tobytes())
    return h.hexdigest()


def total_energy(record: RunRecord) -> tuple[np.ndarray, np.ndarray | None]:
    """Times [s] and total mechanical energy [J] where every subsystem has a sample: the sum over the
    subsystems that report their energy (None when none does)."""
    subs = record.plan.subsystems
    period = math.lcm(*(s.ratio for s in subs))
    ticks = np.arange(0, record.plan.n_ticks + 1, period)
    reporting = [s for s in subs if s.energy_output is not None]
    energy = sum(record.trajectories[s.index][ticks // s.ratio, s.energy_output] for s in reporting) if reporting else None
    return ticks * record.plan.base_step_ns * 1e-9, energy


def energy_growth_rate(t: np.ndarray, energy: np.ndarray) -> float:
    """Exponential growth rate [1/s] of the energy envelope over the second half of the run (0 for a run of
    fewer than four energy samples, too short to show growth)."""
    n_windows = min(ENERGY_WINDOWS, len(t))
    if n_windows < 4:
        return 0.0
    windows = np.array_split(np.arange(len(t)), n_windows)
    centres = np.array([t[w].mean() for w in windows])
    peaks = np.array([np.max(np.abs(energy[w])) for w in windows])
    late = slice(n_windows // 2, None)
    logs = np.log(np.maximum(peaks[late], np.finfo(float).tiny))
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
            ref = reference.signals[name][::sub.ratio]
            entry["nrms"] = nrms(record.signal(name), ref) if finite else None
            if "monolithic" in references:
                entry["nrms_monolithic"] = nrms(references["monolithic"].signals[name][::sub.ratio], ref)
        signals[name] = entry
    return signals


def energy_balance(record: RunRecord, reference: Reference | None, finite: bool) -> dict | None:
    """The ``energy`` entry of the summary; None when no subsystem reports its energy. ``subsystems`` names
    the ones that do, when some do not (an FMU without an energy variable)."""
    t, energy = total_energy(record)
    if energy is None:
        return None
    e0 = float(energy[0])
    balance = {
        "initial": e0, "final": float(energy[-1]), "max": float(np.max(energy)),
        "max_relative_drift": float(np.max(np.abs(energy - e0)) / e0) if e0 > 0 and finite else None,
        "growth_rate_per_s": energy_growth_rate(t, energy) if finite else math.inf,
    }
    if reference is not None:
        balance["reference_final"] = float(reference.energy[-1])
    reporting = [s.name for s in record.plan.subsystems if s.energy_output is not None]
    if len(reporting) < len(record.plan.subsystems):
        balance["subsystems"] = reporting
    return balance


def summarize(scene: Scene, record: RunRecord, bus: str, wall_s: float, references: dict[str, Reference],
              reference_note: str | None = None, recording: dict | None = None) -> dict:
    plan = record.plan
    finite = all(np.isfinite(tr).all() for tr in record.trajectories) and (
        record.implicit is None or record.implicit.diverged_at is None)
    reference = references.get("analytic") or references.get("solve_ivp")  # what the NRMS is measured against
    signals = signal_accuracy(scene, record, references, reference, finite)
    energy_summary = energy_balance(record, reference, finite)
    growth = energy_summary["growth_rate_per_s"] if energy_summary is not None else (0.0 if finite else math.inf)
    timing = run_timing(record, wall_s)
    summary = {
        "scene": scene.name,
        "bus": bus,
        "macro_step": scene.manager.macro_step,
        "duration": scene.manager.duration,
        "steps": plan.n_ticks,
        "extrapolation": scene.manager.extrapolation,
        "reference": None if reference is None else reference.kind,
        "subsystems": {s.name: {"comm_step": s.ratio * scene.manager.macro_step,
                                "micro_step": scene.subsystems[s.name].settings.micro_step,
                                "integrator": scene.subsystems[s.name].settings.integrator, "extrapolation": s.order}
                       for s in plan.subsystems},
        "effects": [f"{s.name}.{e}" for s in plan.subsystems for e in s.effects],
        "stable": bool(finite and growth < STABLE_GROWTH_RATE),
        "signals": signals,
        "energy": energy_summary,
        "residual_energy": {bond.name: float(record.residual_energy[np.isfinite(record.residual_energy[:, b]), b][-1])
                            for b, bond in enumerate(plan.bonds)},
        "timing": timing,
        "digest": digest(record),
        "overrides": list(scene.overrides),
    }
    discrete = discrete_verdict(scene)
    summary["discrete"] = discrete
    if discrete is not None:  # a run that overflowed (initial values near 1e308) is not stable whatever ρ is
        summary["stable"] = discrete["stable"] and finite
    summary["stable_from"] = "measured energy growth" if discrete is None else "exact discrete spectral radius"
    summary["diverged"] = not finite
    summary["diverged_at_s"] = first_non_finite_time(record)
    spikes = residual_power_spikes(record, scene.manager.spikes)
    summary["residual_power_spikes"] = {bond: [i.as_dict() for i in found] for bond, found in spikes.items()}
    summary["reliable"] = not summary["diverged"] and summary["stable"] and not any(spikes.values())
    summary["correction"] = correction_summary(scene, record)
    if record.implicit is not None:
        summary["implicit"] = implicit_summary(scene, record)
    if reference_note:
        summary["reference_note"] = reference_note
    if recording is not None:
        summary["recording"] = recording  # the recorder's end record (recordings.writer)
    non_finite: dict[str, str] = {}
    summary = finite_or_null(summary, "", non_finite)
    summary["non_finite"] = non_finite
    return summary


def first_non_finite_time(record: RunRecord) -> float | None:
    """The first time [s] at which a subsystem's output was not finite (None: every output stayed finite)."""
    times = []
    for sub, trajectory in zip(record.plan.subsystems, record.trajectories):
        rows = np.flatnonzero(~np.isfinite(trajectory).all(axis=1))
        if rows.size:
            times.append(int(rows[0]) * sub.ratio * record.plan.base_step_ns * 1e-9)
    return min(times, default=None)


def discrete_verdict(scene: Scene) -> dict | None:
    """``zencosim analyze``'s verdict on the scheme this scene runs: ``spectral_radius`` ρ, ``growth_rate_per_s``
    ``2 ln ρ / T`` and ``stable`` (ρ <= 1); None when the scene is not linear or corrects energy."""
    # imported here: the analysis needs scipy.optimize, which nothing else of a run's summary loads
    from zencosim.manager.analysis.scene_analysis import run_scheme
    try:
        scheme = run_scheme(scene)
    except (ValueError, ArithmeticError):  # a transition matrix that cannot be built or decomposed (singular)
        return None
    if scheme is None:
        return None
    return {"spectral_radius": scheme.spectral_radius, "growth_rate_per_s": scheme.growth_rate,
            "stable": scheme.stable}


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
    """The energy correction's settings and, per corrected point, the work it injected (None: no correction)."""
    if not record.corrections:
        return None
    settings = scene.manager.correction
    groups = {}
    for log in record.corrections:
        norms = np.linalg.norm(log.force, axis=1)
        groups[log.name] = {"subsystem": log.subsystem, "mu": dict(zip(log.bonds, log.mu)),
                            "work_injected": float(log.work[np.isfinite(log.work)][-1]),
                            "uncorrected_energy": float(log.uncorrected_energy[np.isfinite(log.uncorrected_energy)][-1]),
                            "max_force": float(norms.max()), "capped_steps": log.capped_steps, "steps": log.steps}
    return {"mu": settings.mu, "nu": settings.nu, "cap_fraction": settings.cap_fraction, "cap_force": settings.cap_force,
            "work_injected": sum(g["work_injected"] for g in groups.values()), "points": groups}


def implicit_summary(scene: Scene, record: RunRecord) -> dict:
    """The ``implicit`` entry of the run summary (docs/summary.md)."""
    joint = compile_joint(scene, record.plan)
    runs = record.implicit.corrector_runs
    diverged = record.implicit.diverged_at
    done = runs[:diverged] if diverged is not None else runs
    side_1, side_2 = (record.trajectories[joint.sides[side]][:, joint.outputs[side]] for side in (0, 1))
    gaps = np.abs(side_2 - side_1)[:, :2]  # (ticks, position/velocity, axes)
    finite = np.isfinite(gaps).all(axis=(1, 2))
    return {
        "method": method_name(joint.method),
        "parameters": dataclasses.asdict(joint.method),
        "decomposition": joint.decomposition.name,
        "k": joint.k,
        "corrector_runs": {"mean": float(done.mean()) if len(done) else None, "max": int(done.max(initial=0)),
                           "histogram": {int(n): int(c) for n, c in zip(*np.unique(done, return_counts=True))}},
        "diverged_at_s": None if diverged is None else (diverged + 1) * record.plan.base_step_ns * 1e-9,
        "max_gap": {"position": float(gaps[finite, 0].max()), "velocity": float(gaps[finite, 1].max())},
    }
