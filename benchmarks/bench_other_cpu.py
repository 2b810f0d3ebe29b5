"""What work on the other CPU costs the in-process stepping loop: the recorder's process works there.

    python benchmarks/bench_other_cpu.py [--repeats 6]

CPU µs per macro-step of two_mass_damped's stepping loop (bench_recording.stepping_loop, plain, 2 000 steps),
pinned to CPU 0, with CPU 1 idle and with a process pinned to CPU 1 that spins in Python, compresses with
zstd (as the recorder does) or copies memory; the kinds take turns within each repeat, and each is reported
as the median over repeats and, as bench_recording.py reports an overhead, the median of its ratios to the
idle run of the same repeat, with that median's 95 % confidence interval and the ratios' range. On a machine
whose two CPUs share a core (SMT siblings, or a hypervisor's), what the recorder does there slows the run
beside it. On the 2-vCPU host of docs/recording.md one invocation found +25, +48 and +34 % (spin, zstd,
memcpy; ratios of medians), two later ones −17 to −6 %: that host's own swings are larger than the effect.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_recording import _overhead, _overhead_of, stepping_loop
from rich.console import Console
from rich.table import Table

from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene

STEPS = 2000
NEIGHBOURS = {"spin": "while True: pass",
              "zstd": "import os, zstandard\ndata = os.urandom(1 << 16) * 4\n"
                      "compress = zstandard.ZstdCompressor(level=1).compress\nwhile True: compress(data)",
              "memcpy": "memory = bytearray(64 << 20)\nwhile True: bytes(memory)"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=6)
    args = parser.parse_args()
    if os.cpu_count() < 2:
        sys.exit("needs two CPUs")
    os.sched_setaffinity(0, {0})
    scene = load_scene("two_mass_damped", [f"manager.duration={STEPS / 1000}"])
    found: dict[str, list[float]] = {kind: [] for kind in ("idle", *NEIGHBOURS)}
    for _ in range(args.repeats):
        for kind in found:
            neighbour = None
            if kind != "idle":
                neighbour = subprocess.Popen([sys.executable, "-c",
                                              f"import os\nos.sched_setaffinity(0, {{1}})\n{NEIGHBOURS[kind]}"])
                time.sleep(0.3)  # it runs
            try:
                started = time.thread_time()
                stepping_loop(scene, "plain", *plan_scene(scene))
                found[kind].append((time.thread_time() - started) / STEPS * 1e6)
            finally:
                if neighbour is not None:
                    neighbour.kill()
                    neighbour.wait()
    table = Table(title=f"two_mass_damped stepping loop on CPU 0, medians of {args.repeats}")
    for column in ("CPU 1", "CPU µs per macro-step", "against idle (median of ratios; 95 % CI; range)"):
        table.add_column(column, justify="right")
    for kind, values in found.items():
        table.add_row(kind, f"{statistics.median(values):.1f}",
                      "" if kind == "idle" else _overhead(_overhead_of(values, found["idle"])))
    Console().print(table)


if __name__ == "__main__":
    main()
