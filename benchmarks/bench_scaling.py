"""How the cost of a macro-step grows with the number of subsystems: chains and stars of point masses
(zencosim.scenes.topologies), one mass per subsystem, in process and over Zenoh, all in one run.

    python benchmarks/bench_scaling.py [--sizes 2,3,5,9,17,33] [--duration 1.0] [--repeats 3] [--json out.json]

Per topology and n: µs per macro-step in process and over Zenoh (median over repeats of the stepping loop's
wall time / macro-steps), the replies a subsystem process takes from the network per macro-step (largest
and mean over the processes: its sources' replies), and the CPU time per macro-step of the subsystem
processes together and of the manager, while the run steps (as the processes report it: start-up is left out). Every Zenoh
run's digest is checked against the in-process one.
docs/scaling.md reads the figures and states the cost model they give.
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
from zencosim.manager.run import execute
from zencosim.scenes.topologies import mass_chain, mass_star

TOPOLOGIES = {"chain": mass_chain, "star": mass_star}


def measure(scene, repeats: int) -> dict:
    """Medians over ``repeats`` of the in-process and Zenoh figures of one scene."""
    steps = scene.manager.duration_ns // scene.manager.macro_step_ns
    inproc, zenoh, children, manager, most, mean = [], [], [], [], [], []
    digest = None
    for _ in range(repeats):
        record, wall_s = execute(scene, "inproc")
        inproc.append(wall_s / steps * 1e6)
        digest = zencosim.run(scene).digest if digest is None else digest
        result = zencosim.run(scene, "zenoh")
        reports = result.summary["timing"]["subsystems"]
        children.append(sum(report["cpu_s"] for report in reports.values()) / steps * 1e6)
        manager.append(result.summary["timing"]["manager_cpu_s"] / steps * 1e6)
        if result.digest != digest:
            raise SystemExit(f"{scene.name}: the Zenoh run's digest differs from the in-process one")
        zenoh.append(result.summary["timing"]["wall_s"] / steps * 1e6)
        received = [report["replies_received"] / steps for report in result.summary["timing"]["subsystems"].values()]
        most.append(max(received))
        mean.append(statistics.mean(received))
    return {"inproc_us": statistics.median(inproc), "zenoh_us": statistics.median(zenoh),
            "replies_per_step_max": statistics.median(most), "replies_per_step_mean": statistics.median(mean),
            "subsystem_cpu_us": statistics.median(children), "manager_cpu_us": statistics.median(manager)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="2,3,5,9,17,33")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated seconds per run (1 ms steps)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    sizes = [int(n) for n in args.sizes.split(",")]
    figures = {"cpus": os.cpu_count(), "load_average": os.getloadavg(), "duration_s": args.duration,
               "repeats": args.repeats, "runs": {}}
    table = Table(title=f"µs per macro-step (medians of {args.repeats}), {os.cpu_count()} CPUs, "
                        f"load {os.getloadavg()[0]:.1f}")
    for column in ("topology", "n", "in process", "over Zenoh", "replies/step/process (max, mean)",
                   "CPU/step: subsystems", "manager"):
        table.add_column(column, justify="left" if column == "topology" else "right")
    with tempfile.TemporaryDirectory() as directory:
        for topology, write in TOPOLOGIES.items():
            for n in sizes:
                path = Path(directory) / f"{topology}{n}.toml"
                path.write_text(write(n, duration=args.duration))
                row = measure(zencosim.load_scene(path), args.repeats)
                figures["runs"][f"{topology}/{n}"] = row
                table.add_row(topology, str(n), f"{row['inproc_us']:.0f}", f"{row['zenoh_us']:.0f}",
                              f"{row['replies_per_step_max']:.2f}, {row['replies_per_step_mean']:.2f}",
                              f"{row['subsystem_cpu_us']:.0f}", f"{row['manager_cpu_us']:.0f}")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
