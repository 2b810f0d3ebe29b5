"""The digest of every bundled scene on each bus, and whether it changed.

    python benchmarks/digests.py --buses inproc,zenoh --out digests.json
    python benchmarks/digests.py --buses inproc --compare digests.json

A digest is the sha256 of every output trajectory (docs/summary.md): equal digests mean bit-identical
runs. A restructuring that keeps the behaviour keeps every digest; equal digests across buses are the
runtime's promise. Digests depend on numpy and the platform's floating point, so compare runs made on
one machine with one environment.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import zencosim


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buses", default="inproc", help="comma-separated: inproc, zenoh")
    parser.add_argument("--out", type=Path, help="write the digests as JSON")
    parser.add_argument("--compare", type=Path, help="a JSON file of earlier digests: report every difference")
    args = parser.parse_args()
    earlier = json.loads(args.compare.read_text()) if args.compare else {}
    digests, differ = {}, 0
    for name in zencosim.bundled_scenes():
        for bus in args.buses.split(","):
            key = f"{name}/{bus}"
            digests[key] = zencosim.run(name, bus).digest
            verdict = "" if key not in earlier else ("  unchanged" if earlier[key] == digests[key] else "  CHANGED")
            differ += verdict == "  CHANGED"
            print(f"{key:36} {digests[key][:16]}{verdict}", flush=True)
    for name in {key.split("/")[0] for key in digests}:
        if len({digests[key] for key in digests if key.startswith(name + "/")}) > 1:
            differ += 1
            print(f"{name}: the buses give different digests")
    if args.out:
        args.out.write_text(json.dumps(digests, indent=1) + "\n")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
