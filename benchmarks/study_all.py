"""What accuracy costs in time for the papers' benchmarks: one study per scene, written to docs/accuracy-cost.md.

    python benchmarks/study_all.py [--out docs] [--cache .zencosim-study] [--only two_mass_damped,...]

Runs ``zencosim study`` (``manager.study``) on every scene of ``STUDIES`` with its grid, writes each scene's
report to ``docs/accuracy-cost/<scene>/`` and the summary, with the plots and what compensation, energy
correction, extrapolation order, the Gauss–Seidel scheme and the implicit methods buy, to ``docs/accuracy-cost.md``. Points are cached:
a second run only measures what is new. Prints the wall time of the whole command.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from zencosim.manager.scene.load import load_scene
from zencosim.manager.study.grid import MACRO_STEP, merge_axes, parse_axis
from zencosim.manager.study.report import answer_table, methods_table, plot_label, write_report
from zencosim.manager.study.study import StudyOptions, run_study

EXPLICIT = ("manager.macro_step={steps}", "manager.extrapolation=0,1,2", "manager.compensation=none,eigenstructure",
            "manager.correction.enabled=false,true", "manager.scheme=jacobi,gauss-seidel")
STUDIES = {  # scene: (--set options, --vary options, in-process repeats, what the scene shows)
    # in-process repeats: 3 for the first scene (its costs are the comparison's reference), 1 for the others,
    # so that the whole command takes well under an hour on a shared 2-core machine
    "two_mass_damped": ((), EXPLICIT, 3, "paper 000 §2.3 scenario 2: damped, force–displacement, ZOH at 1 ms"),
    "two_mass_undamped": ((), EXPLICIT, 1, "paper 000 §2.3 scenario 1: undamped, unstable at 1 ms without help"),
    "four_mass": ((), EXPLICIT, 1, "paper 000 §6.2: two 2-DOF subsystems, unstable at 3 ms uncompensated"),
    "double_oscillator": ((), ("manager.macro_step={steps}", "manager.extrapolation=0,1,2",
                               "manager.correction.enabled=false,true", "manager.scheme=jacobi,gauss-seidel"), 1,
                          "paper 002 §3.3 Table 1 case 1 (the undamped two-mass system with paper 002's energy correction)"),
    "constrained_two_mass": ((), ("manager.macro_step={steps}", "manager.extrapolation=0,1,2",
                                  "manager.implicit.method=baumgarte,weighted-multiplier,projection"), 1,
                             "paper 003 §3.7: rigid joint, implicit coupling with rollback"),
    "hydraulic_crane": (("manager.duration=2.0",), ("manager.macro_step=0.25e-3,0.5e-3,1e-3",
                                                    "manager.extrapolation=0,1", "manager.correction.enabled=false,true",
                                                    "manager.scheme=jacobi,gauss-seidel"),
                        1, "paper 002 §4.4: multi-rate, nonlinear; the arm steps at 40 base steps, the cylinder at one; "
                           "the first 2 s of the scene's 10 (its slowest run: 8000 base steps of nonlinear "
                           "micro-steps per point)"),
}
STEP_FACTORS = (0.5, 1.0, 2.0, 4.0)


def axes_of(scene, varies: tuple[str, ...]):
    h = scene.manager.macro_step
    steps = ",".join(f"{h * f:g}" for f in STEP_FACTORS)
    return merge_axes([parse_axis(v.format(steps=steps)) for v in varies])


def baseline(study: dict, scene) -> dict | None:
    """The method that runs the scene as it is (its own values of the varied keys)."""
    document = scene.resolved
    for method in study["methods"]:
        if all(_lookup(document, key) == value for key, value in method["values"].items()):
            return method
    return None


def _lookup(document: dict, key: str):
    node = document
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return {"manager.compensation": "none", "manager.correction.enabled": False,
                    "manager.scheme": "jacobi"}.get(key)
        node = node[part]
    return node


def savings_table(study: dict, scene) -> list[str]:
    """Per method and target: the largest macro-step meeting it, its CPU cost, and that cost against the scene as
    it is (its own largest step meeting the target) and against the cheapest method."""
    base = baseline(study, scene)
    targets = list(study["methods"][0]["targets"])
    head = ["method"]
    for target in targets:
        pct = f"{float(target) * 100:g} %"
        head += [f"step for {pct} [ms]", f"CPU [ms/s] for {pct}", "time saved vs the scene as it is",
                 "cost vs the cheapest"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for method in study["methods"]:
        cells = [plot_label(method["values"]) + (" (the scene as it is)" if method is base else "")]
        for target in targets:
            cost = method["targets"][target]["cost_per_s"]
            base_cost = None if base is None else base["targets"][target]["cost_per_s"]
            costs = [m["targets"][target]["cost_per_s"] for m in study["methods"] if m["targets"][target]["cost_per_s"]]
            step = method["targets"][target]["macro_step"]
            if cost is None:
                saved, relative = "–", "–"
            else:
                saved = "the scene misses it" if base_cost is None else f"{base_cost / cost:.2g}×"
                relative = f"{cost / min(costs):.2g}×"
            cells += ["–" if step is None else f"{step * 1e3:g}", "–" if cost is None else f"{cost * 1e3:.3g}",
                      saved, relative]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def stability_words(method: dict, largest_step: float) -> str:
    if method["stability_limit"]:
        return f"stable up to {method['stability_limit'] * 1e3:.3g} ms (the exact limit)"
    largest = method["largest_stable_macro_step"]
    if largest is None:
        return "unstable at every step of the grid"
    return "stable at every step of the grid" if largest == largest_step else f"stable up to {largest * 1e3:g} ms"


def factor_lines(study: dict, scene) -> list[str]:
    """What each value of each varied setting buys, the other settings as the scene has them: the largest
    macro-step reaching each target with its CPU cost, and how far the method stays stable (the exact stability
    limit where the analysis gives one and the grid crosses it, else the largest stable step of the grid)."""
    methods, base = study["methods"], baseline(study, scene)
    if base is None:
        return ["* the scene's own settings are not in the grid"]
    targets = list(methods[0]["targets"])
    own = [r for r in study["points"] if r["method"] == base["method"] and r["error"] is not None]
    best = min(own, key=lambda r: r["error"], default=None)
    lines = [f"* the scene as it is ({plot_label(base['values'])}): " + (
        "unstable at every step of the grid" if best is None
        else f"its smallest error in the grid is NRMS {best['error']:.3g} at {best['macro_step'] * 1e3:g} ms")]
    for key in base["values"]:
        others = {k: v for k, v in base["values"].items() if k != key}
        members = [m for m in methods if all(m["values"][k] == v for k, v in others.items())]
        if len(members) < 2:
            continue
        parts = []
        for method in members:
            reach = []
            for target in targets:
                at = method["targets"][target]
                pct = f"{float(target) * 100:g} %"
                reach.append(f"{pct} up to {at['macro_step'] * 1e3:g} ms ({at['cost_per_s'] * 1e3:.3g} ms CPU/s)"
                             if at["macro_step"] else f"{pct} nowhere in the grid")
            stable = stability_words(method, max(r["macro_step"] for r in study["points"]))
            parts.append(f"**{method['values'][key]}**: " + ", ".join(reach) + f"; {stable}")
        lines.append(f"* `{key}` — " + " · ".join(parts))
    return lines


def zenoh_lines(study: dict) -> list[str]:
    """The points measured over Zenoh, beside their in-process cost, and the Zenoh macro-step they imply."""
    lines = []
    for row in sorted((r for r in study["points"] if r["zenoh"]), key=lambda r: r["error"] or 0.0, reverse=True):
        zenoh, inproc = row["zenoh"], row["inproc"]
        values = {k: v for k, v in row["values"].items() if k != MACRO_STEP}
        lines.append(f"* {plot_label(values)} at {row['macro_step'] * 1e3:g} ms (NRMS {row['error']:.3g}): "
                     f"{zenoh['loop_wall_per_s'] * 1e3:.3g} ms of wall time per simulated second over Zenoh "
                     f"({zenoh['loop_wall_per_s'] * row['macro_step'] * 1e6:.0f} µs per macro-step, "
                     f"{zenoh['exchanges_per_s']:.0f} commands per simulated second), "
                     f"{inproc['loop_wall_per_s'] * 1e3:.3g} ms in process")
    return lines


def summary_row(name: str, study: dict) -> str:
    """The scene's answer for NRMS ≤ 1 % (the study's first target) as a row of the table that opens the page."""
    answer = study["answers"][0]
    if answer["point"] is None:
        return f"| {name} | none: no stable point of the grid meets it | – | – | – | – |"
    row = next(r for r in study["points"] if r["key"] == answer["point"])
    setting = plot_label({k: v for k, v in row["values"].items() if k != MACRO_STEP})
    tied = f" ({len(answer['tied'])} tied on cost: see its section)" if len(answer["tied"]) > 1 else ""
    zenoh = "–" if answer["zenoh_loop_wall_per_s"] is None else f"{answer['zenoh_loop_wall_per_s'] * 1e3:.3g}"
    return (f"| {name} | {setting}{tied} | {answer['macro_step'] * 1e3:g} "
            f"| {answer['inproc_loop_cpu_per_s'] * 1e3:.3g} | {zenoh} | {answer['error']:.3g} |")


def section(name: str, study: dict, scene, about: str) -> list[str]:
    folder = f"accuracy-cost/{name}"
    run = study["run"]
    lines = [f"## {name}", "", f"{about}. Reference: {study['reference']}; error: NRMS of {study['signal']}; "
             f"{run['points']} points ({len(study['grid']['skipped'])} combinations skipped), "
             f"{run['repeats']} in-process run(s) per point, over Zenoh the cheapest point for each target "
             f"({run['zenoh_points']} points). Full table: [{folder}/study.md]({folder}/study.md).", "",
             *answer_table(study), "",
             "What each setting buys (each value, the other settings as the scene has them):", "",
             *factor_lines(study, scene), "",
             "Over Zenoh (measured):", "", *(zenoh_lines(study) or ["* no point measured"]), "",
             f"![{name}: error against cost]({folder}/error_cost.png)", "",
             f"![{name}: error against macro-step]({folder}/error_step.png)", "",
             f"![{name}: largest stable macro-step]({folder}/stability.png)", "",
             "What each method buys and costs (time saved: the CPU cost of the scene as it is at its own largest step "
             "meeting the target over the method's; cost against the cheapest method meeting the target):", "",
             *savings_table(study, scene), "",
             "Order, stability and reach of every method:", "", *methods_table(study), ""]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs")
    parser.add_argument("--cache", default=".zencosim-study")
    parser.add_argument("--only", help="comma-separated scenes (default: all of STUDIES)")
    parser.add_argument("--workers", type=int, default=0)
    args = parser.parse_args()
    started = time.perf_counter()
    names = args.only.split(",") if args.only else list(STUDIES)
    console = Console(stderr=True)
    sections, answers = [], []
    ran = cached = 0
    for name in names:
        sets, varies, repeats, about = STUDIES[name]
        scene = load_scene(name, list(sets))
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                      console=console) as bar:
            tasks = {}

            def progress(phase: str, done: int, total: int) -> None:
                if phase not in tasks:
                    tasks[phase] = bar.add_task(f"{name} {phase}", total=total)
                bar.update(tasks[phase], completed=done, total=total)

            study = run_study(scene, axes_of(scene, varies),
                              StudyOptions(repeats=repeats, zenoh="answers", workers=args.workers), args.cache, progress)
        folder = args.out / "accuracy-cost" / name
        folder.mkdir(parents=True, exist_ok=True)
        write_report(study, folder)
        sections += section(name, study, scene, about)
        ran, cached = ran + study["run"]["ran"], cached + study["run"]["cached"]
        answers.append(summary_row(name, study))
        console.print(f"{name}: {answers[-1]} ({study['run']['wall_s']:.0f} s)")
    wall = time.perf_counter() - started
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    header = [
        "# What accuracy costs in time: the papers' benchmarks", "",
        "Generated by `python benchmarks/study_all.py` (`zencosim study` on each scene; docs/study.md says what "
        "is measured and how). Error: NRMS of the first output signal against the scene's reference, for stable "
        "points; cost: CPU time of the in-process stepping loop per simulated second (wall times, and wall times "
        "over Zenoh for the cheapest point of each target, are in each scene's table). Stability: the exact "
        "discrete analysis of `zencosim analyze` where the scene is linear and uncorrected, else the run's "
        "verdict.", "",
        f"This run of the command took {wall / 60:.1f} min of wall time on this machine ({os.cpu_count()} cores, "
        f"shared: load average {load} at the end; timings on a loaded machine are upper bounds) and measured "
        f"{ran} of the {ran + cached} points ({cached} read from its cache, measured by earlier runs on the same "
        "machine). Re-run it to measure again (`--cache` keeps measured points: delete it for fresh timings).", "",
        "| scene | cheapest setting for NRMS ≤ 1 % | macro-step [ms] | CPU in process [ms/s] | wall over Zenoh [ms/s] "
        "| NRMS |", "| --- | --- | --- | --- | --- | --- |", *answers, "",
        "A method is named by its varied settings (`extrapolation=1, compensation=eigenstructure, "
        "correction.enabled=false`); a dash: the method never meets the target in the grid.", "",
        "Fixed Jacobi against Gauss–Seidel and the energy-controlled macro-step (ECCO), in macro-steps and CPU for "
        "NRMS ≤ 1 % and 0.1 % on every benchmark the step control runs: "
        "[step-control.md](step-control.md#against-the-best-fixed-step) (`python benchmarks/bench_step_control.py`).",
        ""]
    (args.out / "accuracy-cost.md").write_text("\n".join(header + sections))
    print(f"study_all: {len(names)} scenes in {wall:.0f} s; wrote {args.out / 'accuracy-cost.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
