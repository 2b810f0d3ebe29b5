"""Runtime benchmark: macro-steps per second in-process and over Zenoh, against baselines measured in
the same run (zenoh-python ping-pong between two processes, raw loopback UDP round trip).

    python benchmarks/bench_runtime.py [--repeats 5] [--json out.json]

Reports medians over repeats and the ratios the targets are stated in:
zenoh step / ping-pong round trip (target <= 1.2) and in-process steps/s (target >= 13 000).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

import pingpong  # noqa: E402
from manager.run import execute  # noqa: E402
from manager.scene import load_scene  # noqa: E402

SCENE = "two_mass_damped"


def inprocess_steps_per_s(repeats: int) -> float:
    scene = load_scene(SCENE)
    rates = []
    for _ in range(repeats):
        record, wall = execute(scene, "inproc")
        rates.append(record.plan.n_ticks / wall)
    return statistics.median(rates)


def zenoh_step_s(repeats: int, lowlatency: bool) -> tuple[float, float]:
    """Median over repeats of (median step time [s], steps per second)."""
    from manager.zenoh_session import ZenohOptions
    scene = load_scene(SCENE, ["manager.duration=5.0"])
    steps, rates = [], []
    for _ in range(repeats):
        record, wall = execute(scene, "zenoh", zenoh_options=ZenohOptions(lowlatency))
        steps.append(statistics.median((record.send_time_ns[1:] - record.send_time_ns[:-1]) * 1e-9))
        rates.append(record.plan.n_ticks / wall)
    return statistics.median(steps), statistics.median(rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--round-trips", type=int, default=5000)
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    figures = {"scene": SCENE, "repeats": args.repeats, "cpus": os.cpu_count(),
               "inprocess_steps_per_s": inprocess_steps_per_s(args.repeats)}
    for lowlatency in (True, False):
        label = "lowlatency" if lowlatency else "default"
        step, rate = zenoh_step_s(args.repeats, lowlatency)
        rtt = statistics.median(pingpong.zenoh_round_trips(args.round_trips, lowlatency))
        figures[label] = {"zenoh_step_us": step * 1e6, "zenoh_steps_per_s": rate, "pingpong_rtt_us": rtt * 1e6,
                          "ratio_step_to_pingpong": step / rtt}
    figures["udp_rtt_us"] = statistics.median(pingpong.udp_round_trips(args.round_trips)) * 1e6

    table = Table(title=f"{SCENE}: medians over {args.repeats} runs, {args.round_trips} round trips")
    table.add_column("measure")
    table.add_column("value", justify="right")
    table.add_column("target", justify="right")
    table.add_row("in-process macro-steps/s", f"{figures['inprocess_steps_per_s']:.0f}", ">= 13000")
    for label in ("lowlatency", "default"):
        f = figures[label]
        table.add_row(f"zenoh ({label} transport) macro-step [µs]", f"{f['zenoh_step_us']:.1f}", "")
        table.add_row(f"zenoh-python ping-pong RTT ({label}) [µs]", f"{f['pingpong_rtt_us']:.1f}", "")
        table.add_row(f"ratio macro-step / ping-pong ({label})", f"{f['ratio_step_to_pingpong']:.2f}", "<= 1.2")
    table.add_row("raw loopback UDP RTT [µs]", f"{figures['udp_rtt_us']:.1f}", "")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
