"""``zencosim study``: what accuracy costs in time — sweep a grid of settings, measure every point, write the report."""
from __future__ import annotations

import argparse
import time

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from zencosim.cli.console import UsageError, add_scene_arguments, err, examples, out, say
from zencosim.extras import require
from zencosim.manager.scene.load import Scene, load_scene
from zencosim.manager.study.grid import GridError, default_axes, merge_axes, parse_axis
from zencosim.manager.study.report import answer_table, check_report_folder, write_report
from zencosim.manager.study.study import ZENOH_CHOICES, StudyOptions, run_study

_PHASES = {"inproc": "in process", "zenoh": "over Zenoh"}


class ProgressLines:
    """The study's progress as plain lines on standard output, one per finished point (as pip and pytest report
    when their output is not a terminal): ``two_mass_damped: point 3/16 in process done (12 s)``."""

    def __init__(self, scene_name: str) -> None:
        self.scene_name = scene_name
        self.started_s = time.monotonic()
        self.said: dict[str, int] = {}  # per phase, the number of points done when it last said it

    def point(self, phase: str, done: int, total: int) -> None:
        if self.said.get(phase) == done:
            return
        first = phase not in self.said
        self.said[phase] = done
        if first:  # before any point is measured: what the cache already holds
            cached = "" if not done else ", all from the cache" if done == total else f", {done} from the cache"
            say(f"{self.scene_name}: {total} point{'s' if total != 1 else ''} {_PHASES[phase]}{cached}")
            return
        elapsed_s = time.monotonic() - self.started_s
        say(f"{self.scene_name}: point {done}/{total} {_PHASES[phase]} done ({elapsed_s:.0f} s)")


def _no_signals(scene: Scene) -> str:
    """What to say of a scene whose ``outputs.signals`` lists nothing: a study needs a signal whose NRMS it measures."""
    names = sorted({s for c in scene.couplings.values() for s in c.signals()})
    if not names:
        return (f"{scene.path}: outputs.signals: the scene lists no signal and has no coupling signal; a study "
                "measures the NRMS of one")
    return (f"{scene.path}: outputs.signals: the scene lists no signal; a study measures the NRMS of one: add "
            f"--set 'outputs.signals=[\"{names[0]}\"]' (its coupling signals: {', '.join(names)})")


def cmd_study(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene, args.overrides)
    try:
        axes = merge_axes([parse_axis(text) for text in args.vary]) if args.vary else default_axes(scene)
    except GridError as error:
        raise UsageError(str(error)) from None
    if not scene.outputs.signals:
        raise UsageError(_no_signals(scene))
    signal_name = args.signal or scene.outputs.signals[0]
    if signal_name not in scene.outputs.signals:
        raise UsageError(f"--signal {signal_name}: expected one of the scene's outputs.signals: "
                         f"{', '.join(scene.outputs.signals)}")
    for name, value in (("--repeats", args.repeats), ("--zenoh-repeats", args.zenoh_repeats), ("--workers", args.workers + 1)):
        if value < 1:
            raise UsageError(f"{name}: expected a positive number")
    if not 0 < args.target:
        raise UsageError(f"--target {args.target}: expected a positive NRMS, e.g. 0.01 for 1 %")
    folder = check_report_folder(args.out)
    require("plots", f"the study's plots in {folder}")
    options = StudyOptions(signal_name, args.target, args.repeats, args.zenoh, args.zenoh_repeats, args.workers)
    lines = not args.quiet and not out.is_terminal  # a log, a pipe, CI: a line per point instead of a bar
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                  console=err, disable=args.quiet or lines or not err.is_terminal) as bar:
        tasks = {}
        said = ProgressLines(scene.name)

        def progress(phase: str, done: int, total: int) -> None:
            if lines:
                said.point(phase, done, total)
                return
            if phase not in tasks:
                tasks[phase] = bar.add_task(f"{scene.name}: points {_PHASES[phase]}", total=total)
            bar.update(tasks[phase], completed=done, total=total)

        study = run_study(scene, axes, options, args.cache, progress)
    written = write_report(study, folder)
    if not args.quiet:
        run = study["run"]
        say(f"{run['points']} points ({run['ran']} measured, {run['cached']} from the cache {args.cache}), "
            f"{run['zenoh_points']} over Zenoh, in {run['wall_s']:.1f} s")
        for line in answer_table(study):
            say(line)
        say(f"wrote {', '.join(map(str, written))}")
    return 0


def add_parsers(commands) -> None:
    study = commands.add_parser(
        "study", help="what accuracy costs in time: sweep macro-steps and methods, measure error, stability and cost",
        description="Measure every point of a grid of scene settings: NRMS of the output signals against the "
                    "scene's reference, energy error, stability (exact discrete analysis of linear scenes and "
                    "the run), wall and CPU time per simulated second in process and, for the Pareto points, "
                    "over Zenoh. Points are cached: a study run again measures only new points. Report: "
                    "study.json, study.csv, study.md and plots in --out (docs/study.md).",
        **examples("zencosim study two_mass_damped                     # the default grid of the scene",
                   "zencosim study two_mass_damped --vary manager.macro_step=0.5e-3,1e-3,2e-3,4e-3 "
                   "--vary manager.extrapolation=0,1,2 --vary manager.compensation=none,eigenstructure "
                   "--vary manager.correction.enabled=false,true --out study/",
                   "zencosim study four_mass --set manager.duration=5.001 --signal x3 --target 0.001 --zenoh none"))
    add_scene_arguments(study)
    study.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2,...",
                       help="a scene key and its values (repeatable; manager.macro_step must be one); default: "
                            "the scene's macro-step x 0.5, 1, 2, 4 and the methods its kind admits")
    study.add_argument("--signal", help="the output signal whose NRMS is the error (default: the scene's first)")
    study.add_argument("--target", type=float, default=0.01, help="the NRMS the answer asks for (default 0.01)")
    study.add_argument("--repeats", type=int, default=3, help="in-process runs per point; costs are medians (default 3)")
    study.add_argument("--zenoh", choices=ZENOH_CHOICES, default="pareto",
                       help="points also measured over Zenoh (default: the Pareto front; answers: the cheapest "
                            "point for NRMS <= 1 %% and for 0.1 %%)")
    study.add_argument("--zenoh-repeats", type=int, default=1, help="runs per point over Zenoh (default 1)")
    study.add_argument("--workers", type=int, default=0, help="points measured in parallel (default: one per core)")
    study.add_argument("--cache", default=".zencosim-study", metavar="DIR",
                       help="measured points are kept here (default .zencosim-study)")
    study.add_argument("--out", default="study", metavar="DIR", help="the report's folder (default ./study)")
    study.add_argument("--quiet", action="store_true", help="print nothing but errors")
    study.set_defaults(handler=cmd_study)
