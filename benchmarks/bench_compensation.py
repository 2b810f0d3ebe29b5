"""CPU overhead of eigenstructure compensation per run (paper 000 §5.2.1: +20 %; target here: at most +10 %).

    python benchmarks/bench_compensation.py [--repeats 11] [--json out.json]

For each scene, runs without and with ``manager.compensation = "eigenstructure"`` alternate (so that
a change of machine load hits both), in process. Two figures per run, both CPU time of this process
(``time.process_time``), medians over the repeats:

* run: building the subsystems (with compensation: the design and its discrete correction) plus the
  stepping loop — what a co-simulation costs, as in the paper's Fig. 13;
* loop: the stepping loop alone (compensation adds no work per step: its terms are stamped into the
  subsystems' matrices);

and, timed alone, the design with its discrete correction (``manager.analysis.compensator.scene_compensator``):
its ratio to the uncompensated run is the overhead without the noise of a difference of two runs.

References (analytic solution, monolithic run) are not part of a co-simulation and are not timed.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from zencosim.manager.analysis.compensator import scene_compensator
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.replica import Replica

SCENES = ("two_mass_undamped", "four_mass")


def cpu_times(name: str, compensation: str) -> tuple[float, float]:
    """CPU seconds of (build + loop, loop) for one run."""
    scene = load_scene(name, [f"manager.compensation={compensation}"])
    start = time.process_time()
    plan, subsystems = plan_scene(scene)
    replica = Replica(make_scheme(scene, plan), [s.name for s in plan.subsystems], endpoints(plan, subsystems))
    loop_start = time.process_time()
    replica.run()
    end = time.process_time()
    return end - start, end - loop_start


def design_time(name: str) -> float:
    """CPU seconds of designing and correcting the compensator of a scene."""
    scene = load_scene(name, ["manager.compensation=eigenstructure"])
    start = time.process_time()
    scene_compensator(scene)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=11)
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    figures = {"repeats": args.repeats, "cpus": os.cpu_count(), "scenes": {}}
    table = Table(title=f"CPU time per run, medians over {args.repeats} alternating repeats")
    for column in ("scene", "run [s]", "run, compensated [s]", "overhead", "loop [s]", "loop, compensated [s]",
                   "overhead", "design [s]", "design / run"):
        table.add_column(column, justify="left" if column == "scene" else "right")
    for name in SCENES:
        samples: dict[str, list[tuple[float, float]]] = {"none": [], "eigenstructure": []}
        designs = []
        for _ in range(args.repeats):
            for compensation in samples:
                samples[compensation].append(cpu_times(name, compensation))
            designs.append(design_time(name))
        design = statistics.median(designs)
        medians = {c: [statistics.median(s[i] for s in runs) for i in (0, 1)] for c, runs in samples.items()}
        plain, compensated = medians["none"], medians["eigenstructure"]
        overhead = [compensated[i] / plain[i] - 1.0 for i in (0, 1)]
        figures["scenes"][name] = {"run_s": plain[0], "run_compensated_s": compensated[0], "run_overhead": overhead[0],
                                   "loop_s": plain[1], "loop_compensated_s": compensated[1],
                                   "loop_overhead": overhead[1], "design_s": design,
                                   "design_over_run": design / plain[0]}
        table.add_row(name, f"{plain[0]:.3f}", f"{compensated[0]:.3f}", f"{100 * overhead[0]:+.1f} %",
                      f"{plain[1]:.3f}", f"{compensated[1]:.3f}", f"{100 * overhead[1]:+.1f} %", f"{design:.4f}",
                      f"{100 * design / plain[0]:.1f} %")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
