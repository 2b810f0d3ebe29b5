"""Real-time benchmark: two_mass_damped paced at 1 kHz for 10 s, in process and over Zenoh.

    python benchmarks/bench_realtime.py [--repeats 3] [--duration 10] [--background N] [--json out.json]
    python benchmarks/bench_realtime.py --levers [--background N]   # every lever, over Zenoh

Every run is ``zencosim run two_mass_damped --realtime``; over Zenoh each subsystem process paces its
own replica and the figures are the worse of the two subsystems (docs/summary.md). Reports, per bus,
the median over repeats of the share of missed deadlines and of the p99 and largest lateness
(release time minus deadline), against the targets: at most 1 % missed, p99 lateness at most 0.3 ms,
and how many runs met both. ``--background N`` runs N CPU-bound processes (a Python busy loop each) beside
the runs, started before the first and stopped after the last. ``--levers`` runs over Zenoh only, once per
real-time lever (normal scheduling; SCHED_FIFO priority of the pacing thread; affinity of each subsystem's
pacing thread to a CPU; both), for the table in docs/realtime.md.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console
from rich.table import Table

import zencosim

SCENE = "two_mass_damped"  # macro-step 1 ms: 1 kHz
MISSED_TARGET, P99_TARGET_US = 0.01, 300.0
LEVERS = {  # name → scene overrides
    "normal scheduling": {},
    "SCHED_FIFO 50": {"manager.realtime_priority": 50},
    "affinity": {"manager.realtime_affinity": True},
    "SCHED_FIFO 50 + affinity": {"manager.realtime_priority": 50, "manager.realtime_affinity": True},
}


@contextmanager
def background(n: int):
    """``n`` CPU-bound processes running while the block runs."""
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()


def paced_runs(bus: str, repeats: int, duration_s: float, overrides: dict | None = None) -> dict:
    """The timing of ``repeats`` real-time runs on ``bus``: medians, every run's figures, and how many runs
    met both targets."""
    scene = zencosim.load_scene(SCENE, {"manager.duration": duration_s, **(overrides or {})})
    runs = []
    for _ in range(repeats):
        timing = zencosim.run(scene, bus, realtime=True).summary["timing"]
        steps = round(duration_s / scene.manager.macro_step)
        runs.append({"missed_share": timing["missed_deadlines"] / steps,
                     "lateness_us_median": timing["lateness_us_median"],
                     "lateness_us_p99": timing["lateness_us_p99"], "lateness_us_max": timing["lateness_us_max"]})
    met = sum(run["missed_share"] <= MISSED_TARGET and run["lateness_us_p99"] <= P99_TARGET_US for run in runs)
    return {"median": {k: statistics.median(run[k] for run in runs) for k in runs[0]}, "runs": runs, "met": met}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--duration", type=float, default=10.0, help="simulated (and wall-clock) seconds per run")
    parser.add_argument("--background", type=int, default=0, help="CPU-bound processes running beside the runs")
    parser.add_argument("--levers", action="store_true", help="over Zenoh, once per real-time lever")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    figures = {"scene": SCENE, "rate_hz": 1000, "duration_s": args.duration, "repeats": args.repeats,
               "cpus": os.cpu_count(), "background_processes": args.background, "load_average_before": os.getloadavg()}
    with background(args.background):
        if args.levers:
            rows = {name: paced_runs("zenoh", args.repeats, args.duration, overrides)
                    for name, overrides in LEVERS.items()}
        else:
            rows = {bus: paced_runs(bus, args.repeats, args.duration) for bus in ("inproc", "zenoh")}
    figures["levers" if args.levers else "buses"] = rows
    table = Table(title=f"{SCENE} at 1 kHz for {args.duration:g} s: medians over {args.repeats} runs, "
                        f"{os.cpu_count()} CPUs, {args.background} CPU-bound processes beside")
    for column in ("zenoh, lever" if args.levers else "bus", "missed deadlines", "lateness median [µs]", "p99 [µs]",
                   "max [µs]", "runs meeting both targets"):
        table.add_column(column, justify="right" if table.columns else "left")
    for name, result in rows.items():
        m = result["median"]
        table.add_row(name, f"{100 * m['missed_share']:.2f} %", f"{m['lateness_us_median']:.1f}",
                      f"{m['lateness_us_p99']:.1f}", f"{m['lateness_us_max']:.0f}", f"{result['met']} of {args.repeats}")
    table.add_row("target", f"<= {100 * MISSED_TARGET:g} %", "", f"<= {P99_TARGET_US:g}", "", "")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
