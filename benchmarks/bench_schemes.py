"""What Gauss–Seidel costs against Jacobi over Zenoh, and what it buys, measured in one run.

    python benchmarks/bench_schemes.py [--scene two_mass_damped] [--duration 2] [--repeats 5] [--json FILE]

Each repeat runs the scene over Zenoh (manager and one process per subsystem on loopback) with
``manager.scheme = "jacobi"`` and ``"gauss-seidel"``, in alternating order. Per run: the median wall time of a
macro-step (the run's stepping loop over its steps) and the median step as the subsystems report it
(``timing.step_us_median``): a Jacobi step is one exchange, a Gauss–Seidel step one per stage, each a network hop;
the CPU time of all processes per macro-step, and the NRMS of the scene's
first signal against its reference. Reported: the medians over repeats and the median of the per-repeat ratios
Gauss–Seidel / Jacobi (the two runs of a repeat share the machine's state). On a loaded machine the ratio of
medians is what to read; the digests must equal the in-process ones (checked)."""
from __future__ import annotations

import argparse
import json
import statistics

import zencosim

SCHEMES = ("jacobi", "gauss-seidel")


def measure(scene_name: str, scheme: str, duration: float) -> dict:
    overrides = [f"manager.scheme={scheme}", f"manager.duration={duration!r}"]
    zenoh = zencosim.run(zencosim.load_scene(scene_name, overrides), "zenoh").summary
    inproc = zencosim.run(zencosim.load_scene(scene_name, overrides)).summary
    if zenoh["digest"] != inproc["digest"]:
        raise SystemExit(f"{scene_name} ({scheme}): the digest over Zenoh differs from the in-process one")
    timing = zenoh["timing"]
    cpu_s = sum(s["cpu_s"] for s in timing["subsystems"].values()) + timing["manager_cpu_s"]
    signal = next(iter(zenoh["signals"].values()))
    return {"wall_us_per_step": 1e6 * timing["wall_s"] / zenoh["steps"], "step_us_median": timing["step_us_median"],
            "cpu_us_per_step": 1e6 * cpu_s / zenoh["steps"],
            "nrms": signal.get("nrms")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="two_mass_damped")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", metavar="FILE", help="also write the measurements as JSON")
    args = parser.parse_args()
    runs: dict[str, list[dict]] = {scheme: [] for scheme in SCHEMES}
    for repeat in range(args.repeats):
        for scheme in (SCHEMES if repeat % 2 == 0 else SCHEMES[::-1]):
            runs[scheme].append(measure(args.scene, scheme, args.duration))
    report = {"scene": args.scene, "duration_s": args.duration, "repeats": args.repeats, "runs": runs, "median": {},
              "ratio_gauss_seidel_to_jacobi": {}}
    for key in ("wall_us_per_step", "step_us_median", "cpu_us_per_step"):
        for scheme in SCHEMES:
            report["median"].setdefault(scheme, {})[key] = statistics.median(r[key] for r in runs[scheme])
        report["ratio_gauss_seidel_to_jacobi"][key] = statistics.median(
            g[key] / j[key] for g, j in zip(runs["gauss-seidel"], runs["jacobi"]))
    for scheme in SCHEMES:
        report["median"][scheme]["nrms"] = runs[scheme][0]["nrms"]
    print(f"{args.scene}, {args.duration:g} s over Zenoh, {args.repeats} repeats (medians):")
    for scheme in SCHEMES:
        m = report["median"][scheme]
        print(f"  {scheme:13} wall {m['wall_us_per_step']:8.1f} µs, median step {m['step_us_median']:8.1f} µs, CPU of all processes {m['cpu_us_per_step']:8.1f} "
              f"µs per step   NRMS {m['nrms']:.4g}")
    ratio = report["ratio_gauss_seidel_to_jacobi"]
    print(f"  Gauss–Seidel / Jacobi: wall {ratio['wall_us_per_step']:.2f}x, median step {ratio['step_us_median']:.2f}x, "
          f"CPU {ratio['cpu_us_per_step']:.2f}x")
    if args.json:
        with open(args.json, "w") as out:
            json.dump(report, out, indent=2)


if __name__ == "__main__":
    main()
