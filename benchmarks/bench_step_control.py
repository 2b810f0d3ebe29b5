"""What the energy-controlled macro-step buys against the best fixed step, on every bundled benchmark it runs.

    python benchmarks/bench_step_control.py [--scenes two_mass_damped,...] [--orders 0,1]
        [--methods jacobi,gauss-seidel,energy] [--divisor 10] [--json FILE]

Per scene, with a quantum q = the scene's macro-step / ``--divisor`` (every subsystem integrating at micro-step
q × its comm_ratio in every run, so that the methods integrate alike and differ in their coupling only), for each
extrapolation order:

* fixed, Jacobi and Gauss–Seidel (manager.scheme, its default order): manager.macro_step H = q × 1, 2, 3, 4, 5, 6,
  7, 8, 10, 12, 15, 20, 25, 30, 40, 50, 70, 100; a step whose period (H × the lcm of the comm_ratios) does not divide the duration runs
  to the first whole number of periods past it (its exchanges: that number, as a run that cuts its last step to
  end at the duration takes), against the reference computed that far; a step the scene refuses for another
  reason is listed, with the reason, under ``skipped``;
* energy: manager.step_control = "energy", macro_step q, min_step_size q, max_step_size 100 q, first step q,
  rel_tolerance 0 and abs_tolerance 10^(k/2) J for k = -12 … 6 (docs/step-control.md).

Each run in process: its macro-steps (the exchanges: one command and one reply per subsystem each), its CPU time
and its error, the largest NRMS over the scene's output signals against the scene's reference computed once on
the q grid (sampled at each run's points). Reported per scene: for NRMS <= 1 % and <= 0.1 %, the fewest
exchanges and the CPU time of each method's cheapest run that meets it (over the orders), and the ratio
fixed Jacobi / energy; the largest fixed step whose run stayed bounded (NRMS < 1), per scheme and order. Scenes the energy control refuses (multi-rate, FOH/SOH,
the implicit scheme) are listed with the reason.
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

import zencosim
from zencosim.manager.results.summary import nrms
from zencosim.manager.run import execute, references
from zencosim.manager.scheme.base import SubsystemFailure

FIXED = (1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 15, 20, 25, 30, 40, 50, 70, 100)  # macro-steps in quanta
TOLERANCES = tuple(10.0 ** (k / 2) for k in range(-12, 7))  # abs_tolerance [J]
TARGETS = (1e-2, 1e-3)


def overrides(scene, quantum: float) -> dict:
    """Every subsystem at micro-step ``quantum`` × its communication ratio."""
    return {f"subsystems.{name}.micro_step": quantum * sub.settings.comm_ratio for name, sub in scene.subsystems.items()}


def error(scene, record, reference, quantum_ticks: np.ndarray) -> float:
    """The largest NRMS over the scene's signals, each against the reference at its subsystem's points (every
    comm_ratio-th of the run's, ``quantum_ticks``)."""
    worst = 0.0
    for name in scene.outputs.signals:
        values = np.asarray(record.signal(name))
        if not np.all(np.isfinite(values)):
            return math.inf
        ratio = record.plan.subsystems[record.plan.signals[name][0]].ratio
        worst = max(worst, nrms(values, np.asarray(reference.signals[name])[quantum_ticks[::ratio]]))
    return worst


def run(scene, reference, quantum_ns: int) -> dict:
    """One run's exchanges, CPU time and error; a model that fails (an arm driven out of its geometry by an
    unstable coupling) is an unbounded error."""
    started = time.process_time()
    try:
        with np.errstate(all="ignore"):
            record, _ = execute(scene, "inproc")
    except SubsystemFailure as failure:
        return {"exchanges": None, "cpu_s": time.process_time() - started, "nrms": math.inf, "failed": str(failure)}
    cpu_s = time.process_time() - started
    if record.point_ticks is not None:
        ticks = np.asarray(record.point_ticks) * record.plan.base_step_ns // quantum_ns
    else:
        ticks = np.arange(record.plan.n_ticks + 1) * (record.plan.base_step_ns // quantum_ns)
    worst = error(scene, record, reference, ticks)
    return {"exchanges": len(ticks) - 1, "cpu_s": cpu_s, "nrms": worst}


def cheapest(points: list[dict], target: float) -> dict | None:
    meeting = [p for p in points if p["nrms"] <= target]  # a failed run's is infinite
    return min(meeting, key=lambda p: p["exchanges"]) if meeting else None


def study(name: str, orders: tuple[int, ...], methods: tuple[str, ...], divisor: int) -> dict:
    base = zencosim.load_scene(name)
    quantum = base.manager.macro_step / divisor
    quantum_ns = round(quantum * 1e9)
    fine = {**overrides(base, quantum), "manager.macro_step": quantum}
    energy_keys = {"manager.step_control": "energy", "manager.energy_control.min_step_size": quantum,
                   "manager.energy_control.max_step_size": 100 * quantum, "manager.energy_control.step_size": quantum,
                   "manager.energy_control.rel_tolerance": 0.0}
    try:
        zencosim.load_scene(name, {**fine, **energy_keys})
    except zencosim.SceneError as refused:
        return {"refused": "; ".join(f"{p.key}: {p.reason}" for p in refused.problems)}
    period = math.lcm(*(sub.settings.comm_ratio for sub in base.subsystems.values()))
    longest = max(FIXED) * quantum * period  # the furthest a fixed-step run goes past the duration [s]
    reference_scene = zencosim.load_scene(name, {**fine, "manager.duration": base.manager.duration + longest})
    found, reason = references(reference_scene)
    reference = found.get("analytic") or found.get("solve_ivp")
    if reference is None:
        return {"refused": reason or "no reference"}
    points = {method: [] for method in methods}
    largest_stable, skipped = {}, []
    for order in orders:
        extrapolation = {"manager.extrapolation": order}
        for scheme in [m for m in methods if m != "energy"]:
            for multiple in FIXED:
                step_ns = multiple * quantum_ns
                periods = -(-round(base.manager.duration * 1e9) // (step_ns * period))  # past the duration, whole
                try:
                    scene = zencosim.load_scene(name, {**overrides(base, quantum), **extrapolation,
                                                       "manager.scheme": scheme, "manager.macro_step": step_ns * 1e-9,
                                                       "manager.duration": periods * period * step_ns * 1e-9})
                except zencosim.SceneError as refused:
                    skipped.append({"scheme": scheme, "order": order, "macro_step": multiple * quantum,
                                    "reason": "; ".join(f"{p.key}: {p.reason}" for p in refused.problems)})
                    print(f"{name}	{scheme}, order {order}	{multiple * quantum:g}	skipped: {skipped[-1]['reason']}",
                          flush=True)
                    continue
                point = {"order": order, "macro_step": multiple * quantum, **run(scene, reference, quantum_ns)}
                points[scheme].append(point)
                if math.isfinite(point["nrms"]) and point["nrms"] < 1:
                    largest_stable[f"{scheme}, order {order}"] = point["macro_step"]
                print(f"{name}\t{scheme}, order {order}\t{point['macro_step']:g}\t{point['exchanges']}\t"
                      f"{point['nrms']:.3g}\t{point['cpu_s']:.2f}", flush=True)
        if "energy" not in methods:
            continue
        for tolerance in TOLERANCES:
            scene = zencosim.load_scene(name, {**fine, **energy_keys, **extrapolation,
                                               "manager.energy_control.abs_tolerance": tolerance})
            point = {"order": order, "abs_tolerance": tolerance, **run(scene, reference, quantum_ns)}
            points["energy"].append(point)
            print(f"{name}\tenergy, order {order}\t{tolerance:g}\t{point['exchanges']}\t{point['nrms']:.3g}\t"
                  f"{point['cpu_s']:.2f}", flush=True)
    answers = {f"{target:g}": {method: cheapest(found, target) for method, found in points.items()}
               for target in TARGETS}
    return {"quantum": quantum, "points": points, "answers": answers, "largest_stable_fixed_step": largest_stable,
            "skipped": skipped}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=",".join(zencosim.bundled_scenes()))
    parser.add_argument("--orders", default="0,1", help="extrapolation orders (default 0,1)")
    parser.add_argument("--methods", default="jacobi,gauss-seidel,energy",
                        help="of jacobi, gauss-seidel (fixed steps) and energy (default: all three)")
    parser.add_argument("--divisor", type=int, default=10, help="the quantum: the scene's macro-step over this")
    parser.add_argument("--json", metavar="FILE", help="also write the measurements as JSON")
    args = parser.parse_args()
    orders = tuple(int(order) for order in args.orders.split(","))
    print("scene\tmethod\tstep or tolerance\texchanges\tNRMS\tCPU [s]")
    methods = tuple(args.methods.split(","))
    report = {name: study(name, orders, methods, args.divisor) for name in args.scenes.split(",")}
    print("\nscene\ttarget\t" + "\t".join(f"{m}: exchanges (step or tolerance, order, CPU s)" for m in methods))
    for name, result in report.items():
        if "refused" in result:
            print(f"{name}\trefused: {result['refused']}")
            continue
        for target, answer in result["answers"].items():
            cells = []
            for method in methods:
                p = answer[method]
                setting = "" if p is None else (f"{p['abs_tolerance']:.3g} J" if "abs_tolerance" in p
                                                else f"{p['macro_step']:g} s")
                cells.append("none" if p is None else f"{p['exchanges']} ({setting}, {p['order']}, {p['cpu_s']:.2f})")
            print(f"{name}\t{target}\t" + "\t".join(cells))
        for step in result["skipped"]:
            print(f"{name}\tskipped {step['scheme']}, order {step['order']}, {step['macro_step']:g} s: {step['reason']}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump(report, out, indent=2)


if __name__ == "__main__":
    main()
