"""The cost of mutual TLS per macro-step: two_mass_damped over Zenoh on loopback, tcp/ against tls/.

    python benchmarks/bench_tls.py [--repeats 7] [--duration 5] [--json out.json]

Each repeat runs the scene once over plain TCP and once over mutual TLS (certificates of a certificate
authority made for the benchmark with the ``openssl`` command, the access-control list a TLS run gets),
in alternating order, so that both see the same machine load. A macro-step is the wall time of the
stepping loop over the number of steps (start-up and the TLS handshakes are outside it). Prints the
median macro-step of each, their ratio, and the median of the per-repeat ratios. On a loaded machine
the macro-step varies more from run to run than TLS costs; the ping-pong round trip between two
processes with the bus's settings (``pingpong.py``, ``--round-trips`` of them per repeat, tcp and tls
alternating too) isolates the per-message cost.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.certificates
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pingpong
from rich.console import Console
from rich.table import Table

from tests.certificates import certificate, certificate_authority
from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene

SCENE = "two_mass_damped"


def step_us(scene, options: ZenohOptions) -> float:
    """The mean macro-step [µs] of one run (wall time of the stepping loop / steps)."""
    record, wall_s = execute(scene, "zenoh", zenoh_options=options)
    return wall_s / record.plan.n_ticks * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--duration", type=float, default=5.0, help="simulated time of each run [s]")
    parser.add_argument("--round-trips", type=int, default=5000, help="ping-pongs per repeat and protocol")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    scene = load_scene(SCENE, [f"manager.duration={args.duration}"])
    with tempfile.TemporaryDirectory(prefix="zencosim-bench-tls-") as directory:
        directory = Path(directory)
        certificate_authority(directory, "bench")
        cert, key = certificate(directory, "bench", "host", ["127.0.0.1"])
        tls = ZenohSecurity(tls_ca=directory / "bench-ca.pem", tls_cert=cert, tls_key=key).checked()
        settings = {"tcp": ZenohOptions(True), "tls": ZenohOptions(True, tls)}
        pair = (str(directory / "bench-ca.pem"), str(cert), str(key))
        steps: dict[str, list[float]] = {"tcp": [], "tls": []}
        round_trips: dict[str, list[float]] = {"tcp": [], "tls": []}
        for repeat in range(args.repeats):
            for name in ("tcp", "tls") if repeat % 2 == 0 else ("tls", "tcp"):
                steps[name].append(step_us(scene, settings[name]))
                round_trips[name] += pingpong.zenoh_round_trips(args.round_trips, official=False,
                                                                tls=pair if name == "tls" else None)
    medians = {name: statistics.median(values) for name, values in steps.items()}
    rtt_us = {name: statistics.median(values) * 1e6 for name, values in round_trips.items()}
    figures = {"scene": SCENE, "duration_s": args.duration, "repeats": args.repeats, "cpus": os.cpu_count(),
               "load_average": os.getloadavg(), "step_us": steps,
               "step_us_median_tcp": medians["tcp"], "step_us_median_tls": medians["tls"],
               "ratio_of_medians_tls_to_tcp": medians["tls"] / medians["tcp"],
               "median_ratio_tls_to_tcp": statistics.median(b / a for a, b in zip(steps["tcp"], steps["tls"])),
               "round_trips": args.round_trips * args.repeats, "rtt_us_median_tcp": rtt_us["tcp"],
               "rtt_us_median_tls": rtt_us["tls"], "rtt_ratio_tls_to_tcp": rtt_us["tls"] / rtt_us["tcp"]}
    load = ", ".join(f"{x:.2f}" for x in figures["load_average"])
    table = Table(title=f"{SCENE} over Zenoh on loopback, low-latency transport: medians over {args.repeats} runs "
                        f"of {args.duration:g} s, {os.cpu_count()} CPUs, load average {load}")
    table.add_column("measure")
    table.add_column("value", justify="right")
    table.add_row("macro-step, tcp/ [µs]", f"{medians['tcp']:.1f}")
    table.add_row("macro-step, tls/ with mutual authentication [µs]", f"{medians['tls']:.1f}")
    table.add_row("tls / tcp (ratio of the medians)", f"{figures['ratio_of_medians_tls_to_tcp']:.3f}")
    table.add_row("tls / tcp (median of the per-repeat ratios)", f"{figures['median_ratio_tls_to_tcp']:.3f}")
    table.add_row("ping-pong round trip, tcp/ [µs]", f"{rtt_us['tcp']:.1f}")
    table.add_row("ping-pong round trip, tls/ [µs]", f"{rtt_us['tls']:.1f}")
    table.add_row("tls / tcp (round trip)", f"{figures['rtt_ratio_tls_to_tcp']:.3f}")
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
