"""What a model of one's own costs per macro-step: two_mass_damped with built-in models, with FMUs (FMI 2.0
and 3.0 Co-Simulation, FMI 2.0 Model Exchange with rk4) and with the example Python model, in process
and over Zenoh, all measured in one run.

    python benchmarks/bench_models.py [--repeats 5] [--zenoh-repeats 3] [--json out.json]

The FMUs are built from zencosim/examples/fmus into a temporary directory first (gcc, fmpy). Reports the
median µs per macro-step (wall time of the stepping loop / macro-steps) and its ratio to the built-in
model with the same integrator on the same bus. rk4 takes four evaluations per micro-step where
symplectic Euler takes one, so the Model Exchange FMU is set against the built-in rk4 run.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
from pathlib import Path

from rich.console import Console
from rich.table import Table

import zencosim
from zencosim.examples.write import write_examples
from zencosim.manager.run import execute

RK4 = {"subsystems.S1.integrator": "rk4", "subsystems.S2.integrator": "rk4"}


def step_us(scene, bus: str, repeats: int) -> float:
    """Median over repeats of the stepping loop's wall time per macro-step [µs]."""
    times = []
    for _ in range(repeats):
        record, wall_s = execute(scene, bus)
        times.append(wall_s / record.plan.n_ticks * 1e6)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--zenoh-repeats", type=int, default=3)
    parser.add_argument("--duration", type=float, default=5.0, help="simulated seconds per run (1 ms steps)")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        write_examples(Path(directory))
        duration = {"manager.duration": args.duration}
        cases = {  # label -> (scene, the built-in case it is set against)
            "built-in, symplectic Euler": (zencosim.load_scene("two_mass_damped", duration), None),
            "built-in, rk4": (zencosim.load_scene("two_mass_damped", duration | RK4), None),
            "FMI 2.0 Co-Simulation": (zencosim.load_scene(Path(directory) / "two_mass_damped_fmu.toml", duration),
                                      "built-in, symplectic Euler"),
            "FMI 3.0 Co-Simulation": (zencosim.load_scene(Path(directory) / "two_mass_damped_fmu3.toml", duration),
                                      "built-in, symplectic Euler"),
            "FMI 2.0 Model Exchange, rk4": (zencosim.load_scene(Path(directory) / "two_mass_damped_fmu_me.toml",
                                                                duration), "built-in, rk4"),
            "Python model": (zencosim.load_scene(Path(directory) / "two_mass_damped_python.toml", duration),
                             "built-in, symplectic Euler"),
        }
        figures = {"cpus": os.cpu_count(), "load_average": os.getloadavg(), "duration_s": args.duration,
                   "repeats": {"inproc": args.repeats, "zenoh": args.zenoh_repeats}, "cases": {}}
        for label, (scene, _) in cases.items():
            figures["cases"][label] = {bus: step_us(scene, bus, repeats)
                                       for bus, repeats in (("inproc", args.repeats), ("zenoh", args.zenoh_repeats))}
    table = Table(title=f"two_mass_damped, µs per macro-step (medians), {os.cpu_count()} CPUs")
    for column in ("models", "in process", "ratio", "over Zenoh", "ratio"):
        table.add_column(column, justify="left" if column == "models" else "right")
    for label, (_, against) in cases.items():
        row = figures["cases"][label]
        ratios = {bus: row[bus] / figures["cases"][against][bus] if against else None for bus in row}
        row["ratio"] = ratios
        table.add_row(label, f"{row['inproc']:.1f}", "" if against is None else f"{ratios['inproc']:.2f}",
                      f"{row['zenoh']:.1f}", "" if against is None else f"{ratios['zenoh']:.2f}")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
