"""Peak memory of a run against its simulated length: does a long run stay bounded?

    python benchmarks/bench_memory.py [--durations 10,1000] [--buses inproc,zenoh] [--tree ../before]

Each run is ``zencosim run two_mass_damped --set manager.duration=D --bus B --summary …`` in a fresh
process of its own (the command line's path: run, references, summary, digest). Reported per run: the
peak resident set size of that process (``resource.getrusage(RUSAGE_SELF).ru_maxrss``: in process the
whole run, over Zenoh the manager) and of its largest child (``RUSAGE_CHILDREN``: over Zenoh the
largest subsystem process), and the growth per macro-step between the shortest and the longest run.
``--out FILE.csv`` also writes every signal (``--out``), ``--tree DIR`` measures another source tree
(a checkout of another commit) the same way, for a before/after table from one machine.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_runtime import package_farm
from rich.console import Console
from rich.table import Table

SCENE = "two_mass_damped"
MACRO_STEP_S = 0.001  # the scene's macro-step


def child(bus: str, duration: float, out: str | None) -> None:
    """Run the scene as ``zencosim run`` does and print the peak RSS of this process and its children [kB]."""
    from zencosim.cli.main import main
    with tempfile.TemporaryDirectory() as folder:
        argv = ["run", SCENE, "--bus", bus, "--set", f"manager.duration={duration}", "--quiet",
                "--summary", str(Path(folder) / "summary.json")]
        if out:
            argv += ["--out", str(Path(folder) / out)]
        status = main(argv)
        digest = json.loads((Path(folder) / "summary.json").read_text())["digest"]
    print(json.dumps({"status": status, "self_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                      "children_kb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, "digest": digest}))


def measure(bus: str, duration: float, out: str | None, pythonpath: str | None) -> dict:
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    command = [sys.executable, __file__, "--child", bus, str(duration)] + (["--out", out] if out else [])
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", default="10,1000", help="simulated seconds, comma-separated")
    parser.add_argument("--buses", default="inproc,zenoh")
    parser.add_argument("--out", help="also write every signal to a file of this name (e.g. out.csv)")
    parser.add_argument("--tree", type=Path, help="also measure this source tree (before/after)")
    parser.add_argument("--child", nargs=2, metavar=("BUS", "DURATION"), help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, help="write the figures as JSON")
    args = parser.parse_args()
    if args.child:
        child(args.child[0], float(args.child[1]), args.out)
        return 0
    durations = [float(d) for d in args.durations.split(",")]
    trees = [("this tree", None)]
    farm = None
    if args.tree:
        farm = package_farm(args.tree)
        trees.insert(0, (f"tree {args.tree}", str(farm)))
    rows = []
    try:
        for label, path in trees:
            for bus in args.buses.split(","):
                for duration in durations:
                    figures = measure(bus, duration, args.out, path)
                    rows.append({"tree": label, "bus": bus, "duration_s": duration, **figures})
                    print(json.dumps(rows[-1]), flush=True)
    finally:
        if farm is not None:
            shutil.rmtree(farm)
    table = Table(title=f"peak RSS of {SCENE} (zencosim run --summary{' --out' if args.out else ''})")
    for column in ("tree", "bus", "simulated [s]", "process [MB]", "largest child [MB]", "growth [B/step]"):
        table.add_column(column)
    for row in rows:
        first = next(r for r in rows if r["tree"] == row["tree"] and r["bus"] == row["bus"])
        steps = (row["duration_s"] - first["duration_s"]) / MACRO_STEP_S
        growth = f"{(row['self_kb'] - first['self_kb']) * 1024 / steps:.1f}" if steps else ""
        table.add_row(row["tree"], row["bus"], f"{row['duration_s']:g}", f"{row['self_kb'] / 1024:.1f}",
                      f"{row['children_kb'] / 1024:.1f}" if row["bus"] == "zenoh" else "", growth)
    Console().print(table)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
