"""Paper 002's benchmarks, uncorrected and corrected: the figures docs/numerics.md quotes.

    python benchmarks/paper002.py [--json out.json] [SCENE ...]

For every case: final energy against the reference's, the largest energy deviation from it (both
relative to |E(0)|), NRMS of the scene's first signal, δE, the work the correction injected, and the
flagged δP intervals. Takes about two minutes.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from zencosim.manager.results.summary import summarize, total_energy
from zencosim.manager.run import execute, references
from zencosim.manager.scene.load import load_scene

ON = "manager.correction.enabled=true"
MULTI_RATE = ("manager.macro_step=0.0001", "subsystems.M1.comm_ratio=10", "subsystems.M2.micro_step=0.0001")
CASES = {  # label: (scene, overrides)
    "double oscillator case 1": ("double_oscillator", ("manager.correction.mu=0.5",)),
    "double oscillator case 1, R = 10": ("double_oscillator", MULTI_RATE),
    "double oscillator case 7, nu = 0": ("double_oscillator", ("subsystems.M1.bodies.m1.mass=10",)),
    "double oscillator case 7, nu = 0.25": ("double_oscillator", ("subsystems.M1.bodies.m1.mass=10",
                                                                  "manager.correction.nu=0.25")),
    "multiple oscillator n = 3": ("multiple_oscillator_n3", ()),
    "multiple oscillator n = 5": ("multiple_oscillator_n5", ()),
    "nonlinear oscillator case 1": ("nonlinear_oscillator_case1", ()),
    "nonlinear oscillator case 2": ("nonlinear_oscillator_case2", ()),
    "coupled pendula case 1": ("coupled_pendula", ()),
    "coupled pendula case 2": ("coupled_pendula", ("couplings.c.effects.k.stiffness=50",)),
    "hydraulic crane 10 ms / 0.25 ms": ("hydraulic_crane", ()),
    "hydraulic crane 11.5 ms / 0.1 ms": ("hydraulic_crane_11_5ms", ()),
}


def figures(scene_name: str, overrides: tuple[str, ...], reference) -> dict:
    scene = load_scene(scene_name, overrides)
    record, wall = execute(scene)
    summary = summarize(scene, record, "inproc", wall, reference)
    _, energy = total_energy(record)
    ref_energy = next(iter(reference.values())).energy
    step = (len(ref_energy) - 1) // (len(energy) - 1)
    deviation = (energy - ref_energy[::step]) / abs(energy[0])
    first = scene.outputs.signals[0]
    return {"energy_final_rel": float(deviation[-1]), "energy_max_rel": float(np.max(np.abs(deviation))),
            f"nrms_{first}": summary["signals"][first]["nrms"], "delta_e": summary["residual_energy"],
            "work_injected": None if summary["correction"] is None else summary["correction"]["work_injected"],
            "spikes": {b: [(round(i["start"], 3), round(i["end"], 3), i["peak_w"]) for i in found]
                       for b, found in summary["residual_power_spikes"].items() if found}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", help="labels to run (default: all)")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    results = {}
    for label, (scene_name, overrides) in CASES.items():
        if args.cases and label not in args.cases:
            continue
        reference, _ = references(load_scene(scene_name, overrides))
        results[label] = {state: figures(scene_name, overrides + extra, {k: v for k, v in reference.items()
                                                                          if k != "monolithic"})
                          for state, extra in (("uncorrected", ()), ("corrected", (ON,)))}
        for state, row in results[label].items():
            print(f"{label:36s} {state:11s} " + "  ".join(
                f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
