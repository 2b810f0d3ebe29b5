"""Runtime benchmark: macro-steps per second in-process and over Zenoh, against baselines measured in
the same run (zenoh-python ping-pong between two processes, raw loopback UDP round trip).

    python benchmarks/bench_runtime.py [--repeats 5] [--json out.json]

Reports medians over repeats and the ratios the targets are stated in: the Zenoh macro-step of
two_mass_damped (2 subsystem processes + manager, as fast as possible) over the zenoh-python ping-pong
round trip (target <= 1.2), and in-process macro-steps per second (target >= 13 000).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pingpong
from rich.console import Console
from rich.table import Table

from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene

SCENE = "two_mass_damped"


def inprocess_steps_per_s(repeats: int) -> float:
    scene = load_scene(SCENE)
    rates = []
    for _ in range(repeats):
        record, wall = execute(scene, "inproc")
        rates.append(record.plan.n_ticks / wall)
    return statistics.median(rates)


def zenoh_step_s(repeats: int, lowlatency: bool) -> float:
    """Median over repeats of the mean macro-step time [s] (wall time / steps) of a 5 s run."""
    scene = load_scene(SCENE, ["manager.duration=5.0"])
    steps = []
    for _ in range(repeats):
        record, wall = execute(scene, "zenoh", zenoh_options=ZenohOptions(lowlatency))
        steps.append(wall / record.plan.n_ticks)
    return statistics.median(steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--round-trips", type=int, default=5000)
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    n = args.round_trips
    figures = {
        "scene": SCENE, "repeats": args.repeats, "cpus": os.cpu_count(),
        "inprocess_steps_per_s": inprocess_steps_per_s(args.repeats),
        "zenoh_step_us_lowlatency": zenoh_step_s(args.repeats, True) * 1e6,
        "zenoh_step_us_default_transport": zenoh_step_s(args.repeats, False) * 1e6,
        "pingpong_rtt_us_official": statistics.median(pingpong.zenoh_round_trips(n, official=True)) * 1e6,
        "pingpong_rtt_us_bus_settings": statistics.median(pingpong.zenoh_round_trips(n, official=False)) * 1e6,
        "udp_rtt_us": statistics.median(pingpong.udp_round_trips(n)) * 1e6,
    }
    figures["ratio_step_to_official_pingpong"] = figures["zenoh_step_us_lowlatency"] / figures["pingpong_rtt_us_official"]
    figures["ratio_step_to_pingpong_same_settings"] = (figures["zenoh_step_us_lowlatency"]
                                                       / figures["pingpong_rtt_us_bus_settings"])

    table = Table(title=f"{SCENE}: medians over {args.repeats} runs and {n} round trips, {os.cpu_count()} CPUs")
    table.add_column("measure")
    table.add_column("value", justify="right")
    table.add_column("target", justify="right")
    table.add_row("in-process macro-steps/s", f"{figures['inprocess_steps_per_s']:.0f}", ">= 13000")
    table.add_row("Zenoh macro-step, low-latency transport [µs]", f"{figures['zenoh_step_us_lowlatency']:.1f}", "")
    table.add_row("Zenoh macro-step, default transport [µs]", f"{figures['zenoh_step_us_default_transport']:.1f}", "")
    table.add_row("zenoh-python ping-pong RTT, z_ping/z_pong [µs]", f"{figures['pingpong_rtt_us_official']:.1f}", "")
    table.add_row("ping-pong RTT with the bus's settings [µs]", f"{figures['pingpong_rtt_us_bus_settings']:.1f}", "")
    table.add_row("raw loopback UDP RTT [µs]", f"{figures['udp_rtt_us']:.1f}", "")
    table.add_row("macro-step / z_ping RTT", f"{figures['ratio_step_to_official_pingpong']:.2f}", "<= 1.2")
    table.add_row("macro-step / ping-pong with the same settings", f"{figures['ratio_step_to_pingpong_same_settings']:.2f}", "")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
