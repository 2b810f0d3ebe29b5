"""Real-time benchmark: two_mass_damped paced at 1 kHz for 10 s, in process and over Zenoh.

    python benchmarks/bench_realtime.py [--repeats 3] [--duration 10] [--json out.json]

Every run is ``zencosim run two_mass_damped --realtime``; over Zenoh each subsystem process paces its
own replica and the figures are the worse of the two subsystems (docs/summary.md). Reports, per bus,
the median over repeats of the share of missed deadlines and of the p99 and largest lateness
(release time minus deadline), against the targets: at most 1 % missed, p99 lateness at most 0.3 ms.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
from pathlib import Path

from rich.console import Console
from rich.table import Table

import zencosim

SCENE = "two_mass_damped"  # macro-step 1 ms: 1 kHz


def paced_runs(bus: str, repeats: int, duration_s: float) -> dict:
    """The timing of ``repeats`` real-time runs on ``bus``: medians, and every run's figures."""
    scene = zencosim.load_scene(SCENE, {"manager.duration": duration_s})
    runs = []
    for _ in range(repeats):
        timing = zencosim.run(scene, bus, realtime=True).summary["timing"]
        steps = round(duration_s / scene.manager.macro_step)
        runs.append({"missed_share": timing["missed_deadlines"] / steps,
                     "lateness_us_median": timing["lateness_us_median"],
                     "lateness_us_p99": timing["lateness_us_p99"], "lateness_us_max": timing["lateness_us_max"]})
    return {"median": {k: statistics.median(run[k] for run in runs) for k in runs[0]}, "runs": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--duration", type=float, default=10.0, help="simulated (and wall-clock) seconds per run")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    figures = {"scene": SCENE, "rate_hz": 1000, "duration_s": args.duration, "repeats": args.repeats,
               "cpus": os.cpu_count(), "load_average": os.getloadavg(),
               "buses": {bus: paced_runs(bus, args.repeats, args.duration) for bus in ("inproc", "zenoh")}}
    table = Table(title=f"{SCENE} at 1 kHz for {args.duration:g} s: medians over {args.repeats} runs, "
                        f"{os.cpu_count()} CPUs")
    for column in ("bus", "missed deadlines", "lateness median [µs]", "p99 [µs]", "max [µs]"):
        table.add_column(column, justify="left" if column == "bus" else "right")
    for bus, result in figures["buses"].items():
        m = result["median"]
        table.add_row(bus, f"{100 * m['missed_share']:.2f} %", f"{m['lateness_us_median']:.1f}",
                      f"{m['lateness_us_p99']:.1f}", f"{m['lateness_us_max']:.0f}")
    table.add_row("target", "<= 1 %", "", "<= 300", "")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
