"""What accuracy costs in time for the papers' benchmarks: one study per scene, written to docs/accuracy-cost.md.

    python benchmarks/study_all.py [--out docs] [--cache .zencosim-study] [--only two_mass_damped,...]

Runs ``zencosim study`` (``manager.study``) on every scene of ``STUDIES`` with its grid, writes each scene's
report to ``docs/accuracy-cost/<scene>/`` and the summary, with the plots and what compensation, energy
correction, extrapolation order and the implicit methods buy, to ``docs/accuracy-cost.md``. Points are cached:
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
from zencosim.manager.study.grid import merge_axes, parse_axis
from zencosim.manager.study.report import methods_table, write_report
from zencosim.manager.study.study import StudyOptions, run_study

EXPLICIT = ("manager.macro_step={steps}", "manager.extrapolation=0,1,2", "manager.compensation=none,eigenstructure",
            "manager.correction.enabled=false,true")
STUDIES = {  # scene: (--set options, --vary options, in-process repeats, what the scene shows)
    # in-process repeats: 3 for the first scene (its costs are the comparison's reference), 1 for the others,
    # so that the whole command takes well under an hour on a shared 2-core machine
    "two_mass_damped": ((), EXPLICIT, 3, "paper 000 §2.3 scenario 2: damped, force–displacement, ZOH at 1 ms"),
    "two_mass_undamped": ((), EXPLICIT, 1, "paper 000 §2.3 scenario 1: undamped, unstable at 1 ms without help"),
    "four_mass": ((), EXPLICIT, 1, "paper 000 §6.2: two 2-DOF subsystems, unstable at 3 ms uncompensated"),
    "double_oscillator": ((), ("manager.macro_step={steps}", "manager.extrapolation=0,1,2",
                               "manager.correction.enabled=false,true"), 1,
                          "paper 002 §3.3 Table 1 case 1 (the undamped two-mass system with paper 002's energy correction)"),
    "constrained_two_mass": ((), ("manager.macro_step={steps}", "manager.extrapolation=0,1,2",
                                  "manager.implicit.method=baumgarte,weighted-multiplier,projection"), 1,
                             "paper 003 §3.7: rigid joint, implicit coupling with rollback"),
    "hydraulic_crane": ((), ("manager.macro_step=0.125e-3,0.25e-3,0.5e-3,1e-3", "manager.extrapolation=0,1",
                             "manager.correction.enabled=false,true"), 1,
                        "paper 002 §4.4: multi-rate, nonlinear; the arm steps at 40 base steps, the cylinder at one"),
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
            return {"manager.compensation": "none", "manager.correction.enabled": False}.get(key)
        node = node[part]
    return node


def savings_table(study: dict, scene) -> list[str]:
    """Per method and target: the largest macro-step meeting it, its CPU cost, and the time saved against the
    scene as it is (the baseline) at the same target."""
    base = baseline(study, scene)
    targets = list(study["methods"][0]["targets"])
    head = ["method"]
    for target in targets:
        pct = f"{float(target) * 100:g} %"
        head += [f"step for {pct} [ms]", f"CPU [ms/s] for {pct}", f"saves for {pct}"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for method in study["methods"]:
        cells = [method["method"] + (" (the scene as it is)" if method is base else "")]
        for target in targets:
            reach = method["targets"][target]
            base_cost = None if base is None else base["targets"][target]["cost_per_s"]
            cost = reach["cost_per_s"]
            if cost is None:
                saving = "–"
            elif base_cost is None:
                saving = "baseline misses it"
            else:
                saving = f"{base_cost / cost:.2g}×"
            cells += ["–" if reach["macro_step"] is None else f"{reach['macro_step'] * 1e3:g}",
                      "–" if cost is None else f"{cost * 1e3:.3g}", saving]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def factor_lines(study: dict) -> list[str]:
    """What each value of each varied setting buys, the other settings at their best: the largest macro-step
    reaching each target, the cheapest CPU cost of reaching it, and how far the method stays stable (the exact
    stability limit where the analysis gives one, else the largest stable step of the grid)."""
    methods = study["methods"]
    targets = list(methods[0]["targets"]) if methods else []
    lines = []
    for key in methods[0]["values"] if methods else ():
        values = list(dict.fromkeys(m["values"][key] for m in methods))
        if len(values) < 2:
            continue
        parts = []
        for value in values:
            members = [m for m in methods if m["values"][key] == value]
            reach = []
            for target in targets:
                steps = [m["targets"][target]["macro_step"] for m in members if m["targets"][target]["macro_step"]]
                costs = [m["targets"][target]["cost_per_s"] for m in members if m["targets"][target]["cost_per_s"]]
                pct = f"{float(target) * 100:g} %"
                reach.append(f"{pct} up to {max(steps) * 1e3:g} ms ({min(costs) * 1e3:.3g} ms CPU/s)" if steps
                             else f"{pct} never")
            limits = [m["stability_limit"] or m["largest_stable_macro_step"] for m in members]
            limits = [x for x in limits if x]
            stable = f"stable up to {max(limits) * 1e3:.3g} ms" if limits else "unstable at every step of the grid"
            parts.append(f"**{value}**: " + ", ".join(reach) + f"; {stable}")
        lines.append(f"* `{key}` — " + " · ".join(parts))
    return lines


def zenoh_lines(study: dict) -> list[str]:
    """The points measured over Zenoh, beside their in-process cost, and the Zenoh macro-step they imply."""
    lines = []
    for row in sorted((r for r in study["points"] if r["zenoh"]), key=lambda r: r["error"] or 0.0, reverse=True):
        zenoh, inproc = row["zenoh"], row["inproc"]
        lines.append(f"* {row['method']} at {row['macro_step'] * 1e3:g} ms (NRMS {row['error']:.3g}): "
                     f"{zenoh['loop_wall_per_s'] * 1e3:.3g} ms of wall time per simulated second over Zenoh "
                     f"({zenoh['loop_wall_per_s'] * row['macro_step'] * 1e6:.0f} µs per macro-step, "
                     f"{zenoh['exchanges_per_s']:.0f} commands per simulated second), "
                     f"{inproc['loop_wall_per_s'] * 1e3:.3g} ms in process")
    return lines


def section(name: str, study: dict, scene, about: str) -> list[str]:
    folder = f"accuracy-cost/{name}"
    run = study["run"]
    lines = [f"## {name}", "", f"{about}. Reference: {study['reference']}; error: NRMS of {study['signal']}; "
             f"{run['points']} points ({len(study['grid']['skipped'])} combinations skipped), "
             f"{run['repeats']} in-process run(s) per point, over Zenoh the cheapest point for each target "
             f"({run['zenoh_points']} points). Full table: [{folder}/study.md]({folder}/study.md).", "",
             f"**Answer:** {study['answer']['text']}.", "",
             "What each setting buys (each value at the best of the other settings):", "", *factor_lines(study), "",
             "Over Zenoh (measured):", "", *(zenoh_lines(study) or ["* no point measured"]), "",
             f"![{name}: error against cost]({folder}/error_cost.png)", "",
             f"![{name}: error against macro-step]({folder}/error_step.png)", "",
             f"![{name}: largest stable macro-step]({folder}/stability.png)", "",
             "What each method buys (time saved: CPU cost of the scene as it is at its own largest step meeting the "
             "target, over the method's):", "", *savings_table(study, scene), "",
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
        answers.append(f"| {name} | {study['answer']['text']} |")
        console.print(f"{name}: {study['answer']['text']} ({study['run']['wall_s']:.0f} s)")
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
        f"The whole command took {wall / 60:.1f} min of wall time on this machine ({os.cpu_count()} cores, shared: "
        f"load average {load} at the end; timings on a loaded machine are upper bounds). Re-run it to measure "
        "again (`--cache` keeps measured points: delete it for fresh timings).", "",
        "| scene | answer for NRMS ≤ 1 % |", "| --- | --- |", *answers, "",
        "A method is named by its varied settings (`extrapolation=1, compensation=eigenstructure, "
        "correction.enabled=false`); a dash: the method never meets the target in the grid.", ""]
    (args.out / "accuracy-cost.md").write_text("\n".join(header + sections))
    print(f"study_all: {len(names)} scenes in {wall:.0f} s; wrote {args.out / 'accuracy-cost.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
