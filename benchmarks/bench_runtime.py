"""Runtime benchmark: macro-steps per second in-process and over Zenoh, against baselines measured in
the same run (the plain-Python floor of the same arithmetic, zenoh-python ping-pong between two processes,
raw loopback UDP round trip).

    python benchmarks/bench_runtime.py [--repeats 5] [--json out.json]
    python benchmarks/bench_runtime.py --inprocess-only --tree ../zencosim-before   # before/after, side by side

Reports medians over repeats and the ratios the targets are stated in: the Zenoh macro-step of
two_mass_damped (2 subsystem processes + manager, as fast as possible) over the transport floor of a
Jacobi step (``pingpong.jacobi_lockstep_steps``: two zenoh-python processes in lock step with the bus's
settings, each publishing step j once it holds the other's j-1; target <= 1.2), the CPU time of all its processes
per step over the same floor's, measured just before each run (the median of the repeats' ratios; target <= 1.5)
and the manager's over one subsystem process's (target <= 0.2), and over the zenoh-python ping-pong round trip;
in-process macro-steps per second (target >= 13 000), and the in-process macro-step over the floor
(``benchmarks/floor.py``: the same symplectic-Euler Jacobi arithmetic as one Python loop over floats), each
repeat's floor measured just before its run (target <= 30).

``--tree DIR`` also measures the in-process step of the zencosim source tree at ``DIR`` (a checkout of
another commit), alternating with this one, each repeat in a fresh process of its own: a before/after
table from one run on one machine.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pingpong
from floor import floor_step_s
from rich.console import Console
from rich.table import Table

from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene

SCENE = "two_mass_damped"


def inprocess_step(repeats: int, load=load_scene, run=execute) -> dict:
    """Medians over repeats of the in-process macro-step [µs] (wall and CPU time of the stepping loop), of the
    floor measured just before each run, and of their ratio; ``load`` and ``run``: another tree's
    ``load_scene`` and ``execute``."""
    scene = load(SCENE)
    walls, cpus, floors, ratios = [], [], [], []
    for _ in range(repeats):
        floor_us = floor_step_s(scene, scene.manager.duration_ns // scene.manager.macro_step_ns) * 1e6
        cpu = time.process_time()
        record, wall = run(scene, "inproc")
        cpus.append((time.process_time() - cpu) / record.plan.n_ticks * 1e6)
        walls.append(wall / record.plan.n_ticks * 1e6)
        floors.append(floor_us)
        ratios.append(walls[-1] / floor_us)
    return {"step_us": statistics.median(walls), "step_cpu_us": statistics.median(cpus),
            "floor_us": statistics.median(floors), "ratio_to_floor": statistics.median(ratios)}


def package_farm(tree: Path) -> Path:
    """A folder to put on PYTHONPATH that imports the source tree ``tree`` as ``zencosim`` (its layer folders
    inside the package, as setup.py installs them). A tree from before the package (no ``zencosim`` folder:
    ``manager`` and the others are top-level packages) is put on PYTHONPATH as it is."""
    if not (tree / "zencosim").is_dir():
        return tree.resolve()
    farm = Path(tempfile.mkdtemp(prefix="zencosim-tree-")) / "zencosim"
    farm.mkdir()
    for entry in (tree / "zencosim").iterdir():
        (farm / entry.name).symlink_to(entry.resolve())
    for folder in ("manager", "subsystems", "compensation", "recordings", "scenes"):
        (farm / folder).symlink_to((tree / folder).resolve())
    return farm.parent


def compare_trees(tree: Path, repeats: int) -> dict:
    """The in-process step of this tree and of ``tree``, alternating, one fresh process per repeat each."""
    farm = package_farm(tree)
    flat = ["--flat"] if farm == tree.resolve() else []
    runs = {"this": [], "other": []}
    try:
        for _ in range(repeats):
            for which, path, layout in (("other", str(farm), flat), ("this", "", [])):
                env = {**os.environ, "PYTHONPATH": path}
                out = subprocess.run([sys.executable, __file__, "--measure-inprocess", *layout], env=env,
                                     capture_output=True, text=True, check=True).stdout
                runs[which].append(json.loads(out))
    finally:
        if not flat:
            shutil.rmtree(farm)
    return {which: {key: statistics.median(r[key] for r in measured) for key in measured[0]}
            for which, measured in runs.items()}


def zenoh_step(repeats: int, lowlatency: bool, floor_steps: int = 0) -> dict[str, float]:
    """Medians over repeats of a 5 s run's mean macro-step [s] (wall time / steps), and of the CPU time [s] per step
    of all its processes while they stepped (the subsystem processes' and the manager's), and of the manager's; with
    ``floor_steps``, the lock-step floor's CPU per step (``pingpong.jacobi_lockstep_cpu``) measured just before each
    run too, and the ratio of the two of each repeat (the machine's load drifts between repeats: a ratio of
    neighbours is steadier than one of medians taken minutes apart)."""
    scene = load_scene(SCENE, ["manager.duration=5.0"])
    runs = []
    for _ in range(repeats):
        floor = pingpong.jacobi_lockstep_cpu(floor_steps) if floor_steps else None
        record, wall = execute(scene, "zenoh", zenoh_options=ZenohOptions(lowlatency))
        steps = record.plan.n_ticks
        subsystems = [report["cpu_s"] / steps for report in record.reported_timing.values()]
        cpu = sum(subsystems) + record.manager_cpu_s / steps
        runs.append({"step_s": wall / steps, "cpu_s": cpu, "manager_cpu_s": record.manager_cpu_s / steps,
                     "subsystem_cpu_s": max(subsystems),
                     **({"floor_cpu_s": floor, "cpu_ratio": cpu / floor} if floor else {})})
    return {key: statistics.median(run[key] for run in runs) for key in runs[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--round-trips", type=int, default=5000)
    parser.add_argument("--json", help="write the figures as JSON")
    parser.add_argument("--inprocess-only", action="store_true", help="only the in-process step and its floor")
    parser.add_argument("--tree", type=Path, help="also measure the in-process step of this source tree (before/after)")
    parser.add_argument("--measure-inprocess", action="store_true", help=argparse.SUPPRESS)  # one repeat, as JSON
    parser.add_argument("--flat", action="store_true", help=argparse.SUPPRESS)  # ... of a tree before the package
    args = parser.parse_args()
    if args.measure_inprocess:
        if args.flat:
            import manager.run
            import manager.scene
            measured = inprocess_step(1, manager.scene.load_scene, manager.run.execute)
            print(json.dumps({**measured, "package": str(Path(manager.__file__).parent)}))
            return
        import zencosim
        print(json.dumps({**inprocess_step(1), "package": str(Path(zencosim.__file__).parent)}))
        return
    n = args.round_trips
    inproc = inprocess_step(args.repeats)
    figures = {
        "scene": SCENE, "repeats": args.repeats, "cpus": os.cpu_count(), "load_average": os.getloadavg(),
        "inprocess_steps_per_s": 1e6 / inproc["step_us"],
        "inprocess_step_us": inproc["step_us"], "inprocess_step_cpu_us": inproc["step_cpu_us"],
        "floor_step_us": inproc["floor_us"], "ratio_step_to_floor": inproc["ratio_to_floor"],
    }
    if not args.inprocess_only:
        lowlatency = zenoh_step(args.repeats, True, n)
        figures.update({
            "zenoh_step_us_lowlatency": lowlatency["step_s"] * 1e6,
            "zenoh_cpu_us_per_step": lowlatency["cpu_s"] * 1e6,
            "zenoh_manager_cpu_us_per_step": lowlatency["manager_cpu_s"] * 1e6,
            "zenoh_subsystem_cpu_us_per_step": lowlatency["subsystem_cpu_s"] * 1e6,
            "zenoh_step_us_default_transport": zenoh_step(args.repeats, False)["step_s"] * 1e6,
            "jacobi_floor_step_us": statistics.median(statistics.mean(pingpong.jacobi_lockstep_steps(n))
                                                      for _ in range(args.repeats)) * 1e6,
            "jacobi_floor_cpu_us_per_step": lowlatency["floor_cpu_s"] * 1e6,
            "pingpong_rtt_us_official": statistics.median(pingpong.zenoh_round_trips(n, official=True)) * 1e6,
            "pingpong_rtt_us_bus_settings": statistics.median(pingpong.zenoh_round_trips(n, official=False)) * 1e6,
            "udp_rtt_us": statistics.median(pingpong.udp_round_trips(n)) * 1e6,
        })
        figures["ratio_step_to_jacobi_floor"] = figures["zenoh_step_us_lowlatency"] / figures["jacobi_floor_step_us"]
        figures["ratio_cpu_to_jacobi_floor"] = lowlatency["cpu_ratio"]  # the median of each repeat's
        figures["ratio_manager_to_subsystem_cpu"] = (figures["zenoh_manager_cpu_us_per_step"]
                                                     / figures["zenoh_subsystem_cpu_us_per_step"])
        figures["ratio_step_to_official_pingpong"] = figures["zenoh_step_us_lowlatency"] / figures["pingpong_rtt_us_official"]
        figures["ratio_step_to_pingpong_same_settings"] = (figures["zenoh_step_us_lowlatency"]
                                                           / figures["pingpong_rtt_us_bus_settings"])
    if args.tree:
        figures["trees"] = compare_trees(args.tree, args.repeats)

    load = ", ".join(f"{x:.2f}" for x in figures["load_average"])
    table = Table(title=f"{SCENE}: medians over {args.repeats} runs and {n} round trips, {os.cpu_count()} CPUs, "
                        f"load average {load}")
    table.add_column("measure")
    table.add_column("value", justify="right")
    table.add_column("target", justify="right")
    table.add_row("in-process macro-steps/s", f"{figures['inprocess_steps_per_s']:.0f}", ">= 13000")
    table.add_row("in-process macro-step, wall / CPU [µs]", f"{inproc['step_us']:.2f} / {inproc['step_cpu_us']:.2f}", "")
    table.add_row("floor: the same arithmetic as one Python loop [µs]", f"{inproc['floor_us']:.3f}", "")
    table.add_row("in-process macro-step / floor", f"{inproc['ratio_to_floor']:.1f}", "<= 30")
    if not args.inprocess_only:
        table.add_row("Zenoh macro-step, low-latency transport [µs]", f"{figures['zenoh_step_us_lowlatency']:.1f}", "")
        table.add_row("Zenoh macro-step, default transport [µs]", f"{figures['zenoh_step_us_default_transport']:.1f}", "")
        table.add_row("Jacobi transport floor: two processes in lock step [µs]",
                      f"{figures['jacobi_floor_step_us']:.1f}", "")
        table.add_row("zenoh-python ping-pong RTT, z_ping/z_pong [µs]", f"{figures['pingpong_rtt_us_official']:.1f}", "")
        table.add_row("ping-pong RTT with the bus's settings [µs]", f"{figures['pingpong_rtt_us_bus_settings']:.1f}", "")
        table.add_row("raw loopback UDP RTT [µs]", f"{figures['udp_rtt_us']:.1f}", "")
        table.add_row("Zenoh macro-step / Jacobi transport floor", f"{figures['ratio_step_to_jacobi_floor']:.2f}", "<= 1.2")
        table.add_row("CPU of all processes per step: run / lock-step floor [µs]",
                      f"{figures['zenoh_cpu_us_per_step']:.1f} / {figures['jacobi_floor_cpu_us_per_step']:.1f} = "
                      f"{figures['ratio_cpu_to_jacobi_floor']:.2f}", "<= 1.5")
        table.add_row("manager CPU / one subsystem process's, per step [µs]",
                      f"{figures['zenoh_manager_cpu_us_per_step']:.1f} / {figures['zenoh_subsystem_cpu_us_per_step']:.1f}"
                      f" = {figures['ratio_manager_to_subsystem_cpu']:.2f}", "<= 0.2")
        table.add_row("macro-step / z_ping RTT", f"{figures['ratio_step_to_official_pingpong']:.2f}", "")
        table.add_row("macro-step / ping-pong with the same settings",
                      f"{figures['ratio_step_to_pingpong_same_settings']:.2f}", "")
    for which, label in (("other", f"tree {args.tree}"), ("this", "this tree")) if args.tree else ():
        measured = figures["trees"][which]
        table.add_row(f"{label}: in-process step wall / CPU [µs], floor [µs], ratio",
                      f"{measured['step_us']:.2f} / {measured['step_cpu_us']:.2f}, {measured['floor_us']:.3f}, "
                      f"{measured['ratio_to_floor']:.1f}", "")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
