"""Every signal of every bundled scene, saved in one tree and compared with another's: what a change did to the outputs.

    git worktree add /tmp/old 9ff5da8                            # the tree before the change
    python benchmarks/compare_outputs.py capture before.npz --tree /tmp/old
    python benchmarks/compare_outputs.py capture after.npz       # this tree
    python benchmarks/compare_outputs.py compare before.npz after.npz

``capture`` runs every bundled scene in process for ``DURATION`` s (its own duration where that is shorter than one
period), and the hydraulic crane with energy correction and the undamped pair with the eigenstructure compensator
besides (``--tree``: of another source tree, imported as bench_runtime.py does), and saves every signal of each run
(outputs, residual power and energy) and the NRMS of its summary. ``compare`` sorts the signals into bit-identical,
exactly negated (a sign convention that moved) and changed, the last with their largest relative difference, and
says whether every summary's NRMS is the same; exit 1 when any signal changed otherwise. Stop 28's sign
convention: 157 identical, 23 negated (the coupling forces), 0 changed. ``--tolerance R``: a change whose largest
difference is within ``R`` of the signal's range (its largest magnitude over the run) passes; the pointwise relative
difference is printed beside it, large where a signal crosses zero. Stop 31's straight-line steps: 73 identical,
107 changed, the largest 4.6e-14 of a range (``--tolerance 1e-12``, issue 26's bound).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

DURATION = 0.5  # [s] of each scene: enough steps to carry any change, short enough for the whole set
EXTRA = {"hydraulic_crane": ["manager.correction.enabled=true"],
         "two_mass_undamped": ["manager.compensation=eigenstructure"]}  # run a second time with these


def capture(out: str) -> None:
    import zencosim
    runs = [(name, name, []) for name in zencosim.bundled_scenes()]
    runs += [(f"{name}+", name, overrides) for name, overrides in EXTRA.items()]
    data = {}
    for label, name, overrides in runs:
        try:
            scene = zencosim.load_scene(name, overrides + [f"manager.duration={DURATION}"])
        except zencosim.SceneError:  # a scene whose period is longer than DURATION
            scene = zencosim.load_scene(name, overrides)
        result = zencosim.run(scene)
        for signal, values in result.signals.items():
            data[f"{label}|{signal}"] = np.asarray(values.values)
        nrms = {signal: entry.get("nrms") for signal, entry in result.summary.get("signals", {}).items()}
        data[f"{label}|summary"] = np.array(json.dumps(nrms, sort_keys=True, default=str))
        print(f"{label}: {len(result.signals)} signals, digest {result.digest[:16]}", flush=True)
    np.savez(out, **data)


def compare(before: str, after: str, tolerance: float = 0.0) -> int:
    a, b = np.load(before), np.load(after)
    if set(a.files) != set(b.files):
        print(f"different signals: {sorted(set(a.files) ^ set(b.files))}")
        return 1
    identical, negated, changed, summaries = [], [], [], []
    for key in sorted(a.files):
        x, y = a[key], b[key]
        if key.endswith("|summary"):
            if str(x) != str(y):
                summaries.append(key)
        elif np.array_equal(x, y, equal_nan=True):
            identical.append(key)
        elif np.array_equal(x, -y, equal_nan=True):
            negated.append(key)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                pointwise = float(np.nanmax(np.abs(x - y) / np.maximum(np.abs(x), 1e-300)))
                of_range = float(np.nanmax(np.abs(x - y)) / max(float(np.nanmax(np.abs(x))), 1e-300))
            changed.append((key, of_range, pointwise))
    print(f"bit-identical: {len(identical)}")
    print(f"exactly negated: {len(negated)}: {', '.join(negated)}")
    print(f"changed: {len(changed)}" + "".join(f"\n  {key}: largest difference {r:.3g} of its range "
                                               f"({p:.3g} pointwise)" for key, r, p in changed))
    if changed:
        worst = max(changed, key=lambda entry: entry[1])
        print(f"largest change: {worst[1]:.3g} of its range, {worst[0]} (tolerance {tolerance:g})")
    print("summaries' NRMS: " + ("the same" if not summaries else f"differ in {', '.join(summaries)}"))
    return 1 if any(of_range > tolerance for _, of_range, _ in changed) else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    captured = commands.add_parser("capture")
    captured.add_argument("out")
    captured.add_argument("--tree", type=Path, help="capture another source tree's outputs (e.g. a git worktree)")
    compared = commands.add_parser("compare")
    compared.add_argument("before")
    compared.add_argument("after")
    compared.add_argument("--tolerance", type=float, default=0.0,
                          help="largest change, relative to a signal's range, that passes (default 0: none)")
    args = parser.parse_args()
    if args.command == "capture" and args.tree is not None:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_runtime import package_farm
        farm = package_farm(args.tree)
        try:
            return subprocess.run([sys.executable, __file__, "capture", args.out],
                                  env={**os.environ, "PYTHONPATH": str(farm)}).returncode
        finally:
            if farm != args.tree.resolve():
                shutil.rmtree(farm)
    if args.command == "capture":
        capture(args.out)
        return 0
    return compare(args.before, args.after, args.tolerance)


if __name__ == "__main__":
    sys.exit(main())
