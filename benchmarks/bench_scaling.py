"""How the cost of a macro-step grows with the number of subsystems: chains and stars of point masses
(zencosim.scenes.topologies), one mass per subsystem, in process and over Zenoh, all in one run.

    python benchmarks/bench_scaling.py [--sizes 2,3,5,9,17,33] [--duration 1.0] [--repeats 3] [--json out.json]

Per topology and n: µs per macro-step in process and over Zenoh (median over repeats of the stepping loop's
wall time / macro-steps), the replies a subsystem process takes from the network per macro-step (largest
and mean over the processes: its sources' replies), and the CPU time per macro-step of the subsystem
processes together, of one process (mean and largest: issue 26 asks that a chain's stay the same as n grows)
and of the manager, while the run steps (as the processes report it: start-up is left out). Every Zenoh
run's digest is checked against the in-process one. Each row is printed (tab-separated) and, with ``--json``,
written as soon as it is measured, so that a run that ends early keeps the rows it measured.

The cost model (docs/scaling.md) is fitted from the same runs: every subsystem process's CPU time per
macro-step against the replies it takes per macro-step, ``cpu = a + b * replies`` (least squares over
every process of every run), and the hop latency ``L`` from the two-subsystem chain, whose two processes
each had a core: ``L = step(chain 2) - (a + b)``. With one core per subsystem a step then takes
``L + a + b * r_max`` (r_max: the largest fan-in); on this machine, with fewer cores than processes, at
least the CPU of all processes shared over the cores. The table compares both with what was measured.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import zencosim
from zencosim.manager.run import execute
from zencosim.scenes.topologies import mass_chain, mass_star

TOPOLOGIES = {"chain": mass_chain, "star": mass_star}


def measure(scene, repeats: int) -> dict:
    """Medians over ``repeats`` of the in-process and Zenoh figures of one scene."""
    steps = scene.manager.duration_ns // scene.manager.macro_step_ns
    inproc, zenoh, children, manager, most, mean, points, per_process = [], [], [], [], [], [], [], []
    digest = None
    for _ in range(repeats):
        record, wall_s = execute(scene, "inproc")
        inproc.append(wall_s / steps * 1e6)
        digest = zencosim.run(scene).digest if digest is None else digest
        result = zencosim.run(scene, "zenoh")
        reports = result.summary["timing"]["subsystems"]
        children.append(sum(report["cpu_s"] for report in reports.values()) / steps * 1e6)
        per_process.append(max(report["cpu_s"] for report in reports.values()) / steps * 1e6)
        manager.append(result.summary["timing"]["manager_cpu_s"] / steps * 1e6)
        if result.digest != digest:
            raise SystemExit(f"{scene.name}: the Zenoh run's digest differs from the in-process one")
        zenoh.append(result.summary["timing"]["wall_s"] / steps * 1e6)
        received = [report["replies_received"] / steps for report in reports.values()]
        points += [(report["replies_received"] / steps, report["cpu_s"] / steps * 1e6) for report in reports.values()]
        most.append(max(received))
        mean.append(statistics.mean(received))
    return {"inproc_us": statistics.median(inproc), "zenoh_us": statistics.median(zenoh),
            "replies_per_step_max": statistics.median(most), "replies_per_step_mean": statistics.median(mean),
            "subsystem_cpu_us": statistics.median(children), "manager_cpu_us": statistics.median(manager),
            "process_cpu_us_mean": statistics.median(children) / len(reports),
            "process_cpu_us_max": statistics.median(per_process), "processes": points}


def fit_cost_model(runs: dict) -> dict:
    """``cpu = a + b * replies`` per process and step over every process of every run, and the hop latency."""
    replies, cpu = np.array([p for row in runs.values() for p in row["processes"]]).T
    b, a = np.polyfit(replies, cpu, 1)
    latency = runs["chain/2"]["zenoh_us"] - (a + b) if "chain/2" in runs else float("nan")
    return {"cpu_per_step_us": float(a), "cpu_per_reply_us": float(b), "hop_latency_us": float(latency)}


def predicted_us(model: dict, row: dict, n: int, cores: int) -> tuple[float, float]:
    """µs per step with one core per subsystem, and on ``cores`` cores shared by the n processes and the manager."""
    own_core = model["hop_latency_us"] + model["cpu_per_step_us"] + model["cpu_per_reply_us"] * row["replies_per_step_max"]
    total_cpu = n * model["cpu_per_step_us"] + model["cpu_per_reply_us"] * row["replies_per_step_mean"] * n
    return own_core, max(own_core, (total_cpu + row["manager_cpu_us"]) / cores)


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
    columns = ("topology", "n", "in process", "over Zenoh", "replies/step/process (max, mean)",
               "CPU/step: subsystems", "per process (mean, max)", "manager")
    for column in columns:
        table.add_column(column, justify="left" if column == "topology" else "right")
    print("\t".join(columns), flush=True)  # each row as it is measured: a long run that ends early keeps its rows
    with tempfile.TemporaryDirectory() as directory:
        for topology, write in TOPOLOGIES.items():
            for n in sizes:
                path = Path(directory) / f"{topology}{n}.toml"
                path.write_text(write(n, duration=args.duration))
                row = measure(zencosim.load_scene(path), args.repeats)
                figures["runs"][f"{topology}/{n}"] = row
                cells = (topology, str(n), f"{row['inproc_us']:.0f}", f"{row['zenoh_us']:.0f}",
                         f"{row['replies_per_step_max']:.2f}, {row['replies_per_step_mean']:.2f}",
                         f"{row['subsystem_cpu_us']:.0f}",
                         f"{row['process_cpu_us_mean']:.0f}, {row['process_cpu_us_max']:.0f}",
                         f"{row['manager_cpu_us']:.0f}")
                table.add_row(*cells)
                print("\t".join(cells), flush=True)
                if args.json:
                    Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    model = figures["model"] = fit_cost_model(figures["runs"])
    fit = Table(title=f"cost model: CPU per process and step = {model['cpu_per_step_us']:.1f} µs + "
                      f"{model['cpu_per_reply_us']:.1f} µs per reply taken; hop latency {model['hop_latency_us']:.0f} µs")
    for column in ("topology", "n", "measured [µs/step]", f"model, {os.cpu_count()} cores", "model, a core each"):
        fit.add_column(column, justify="left" if column == "topology" else "right")
    for name, row in figures["runs"].items():
        topology, n = name.split("/")
        own_core, here = predicted_us(model, row, int(n), os.cpu_count())
        row["model_us"] = {"own_core": own_core, "here": here}
        fit.add_row(topology, n, f"{row['zenoh_us']:.0f}", f"{here:.0f}", f"{own_core:.0f}")
    Console().print(table)
    Console().print(fit)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
