"""The digest of every bundled scene on each bus, and whether it changed.

    python benchmarks/digests.py --buses inproc,zenoh --out digests.json
    python benchmarks/digests.py --buses inproc --compare digests.json
    python benchmarks/digests.py --examples --set manager.correction.enabled=true --out corrected.json

A digest is the sha256 of every output trajectory (docs/summary.md): equal digests mean bit-identical
runs. A restructuring that keeps the behaviour keeps every digest; equal digests across buses are the
runtime's promise. Digests depend on numpy and the platform's floating point, so compare runs made on
one machine with one environment. ``--examples`` adds the example scenes (``zencosim examples``: FMUs built
here, Python models); ``--set`` applies an override to every scene, and a scene that refuses it is listed as such.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import zencosim
from zencosim.manager.scene.load import SceneError


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buses", default="inproc", help="comma-separated: inproc, zenoh")
    parser.add_argument("--out", type=Path, help="write the digests as JSON")
    parser.add_argument("--compare", type=Path, help="a JSON file of earlier digests: report every difference")
    parser.add_argument("--examples", action="store_true", help="also the example scenes (zencosim examples)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an override for every scene")
    args = parser.parse_args()
    earlier = json.loads(args.compare.read_text()) if args.compare else {}
    scenes = {name: name for name in zencosim.bundled_scenes()}
    if args.examples:
        folder = Path(tempfile.mkdtemp(prefix="zencosim-digests-"))
        subprocess.run([sys.executable, "-m", "zencosim", "examples", str(folder)], check=True, capture_output=True)
        scenes.update({path.name: str(path) for path in sorted(folder.glob("*.toml"))})
    digests, differ = {}, 0
    for name, source in scenes.items():
        try:
            scene = zencosim.load_scene(source, args.set)
        except SceneError:
            print(f"{name:36} refuses {' '.join(args.set)}")
            continue
        for bus in args.buses.split(","):
            key = f"{name}/{bus}"
            digests[key] = zencosim.run(scene, bus).digest
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
