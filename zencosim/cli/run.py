"""``zencosim run``: run a scene on either bus, print its summary, write its results."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from zencosim.cli.console import UsageError, add_scene_arguments, err, examples, out, say, share, warn
from zencosim.cli.credentials import add_security_arguments, given_security_options, security_options
from zencosim.extras import require
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.realtime_probe import Budget
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.results.tables import check_table_path, record_tables, write_tables
from zencosim.manager.run import BUSES, execute, summarize_run
from zencosim.manager.scene.load import SYSTEM_DESCRIPTIONS, load_scene
from zencosim.subsystems.models.external.fmi_steps import uncompiled_fmus

DIVERGED = 3  # exit status of a run whose values did not stay finite, or that --strict fails (zencosim.cli.main)


def _print_summary(summary: dict) -> None:
    control = summary.get("step_control")
    steps = (f"{summary['macro_step']:g} s" if control is None else
             f"{control['min_step']:g} … {control['max_step']:g} s, energy-controlled (mean {control['mean_step']:g} s)")
    table = Table(title=f"{summary['scene']} on the {summary['bus']} bus: {summary['steps']} macro-steps of {steps}")
    table.add_column("quantity")
    table.add_column("value", justify="right")

    def row(label: str, value: str) -> None:
        table.add_row(escape(label), escape(value))

    if summary["diverged"]:
        at = summary["diverged_at_s"]
        row("DIVERGED", "the implicit run's joint opened" if at is None else f"outputs not finite from t = {at:g} s")
    discrete = summary["discrete"]
    if discrete is not None:
        row("stable (exact discrete, as zencosim analyze)", f"{'yes' if summary['stable'] else 'NO'}: spectral radius "
            f"{discrete['spectral_radius']:.12f}, energy growth 2 ln ρ / T = {discrete['growth_rate_per_s']:.4g} 1/s"
            + _growth_time_scale(summary))
    elif summary["stable"] is None:
        candidates = summary.get("energy_candidates") or []
        row("stable", "no verdict: no subsystem reports its energy; declare it, as "
            + (", ".join(f"subsystems.{c.split('.')[0]}.energy = {c.split('.', 1)[1]!r}" for c in candidates)
               if candidates else "subsystems.<name>.energy = '<its output in J>'"))
    elif summary["stable_from"] == "measured energy growth":
        row("stable (measured energy growth)", "yes" if summary["stable"] else "NO (energy grows)")
    else:
        row("stable", "NO (outputs not finite)")
    control = summary.get("step_control")
    if control is not None and control["at_limit"] is not None:
        row("macro-step at a bound", _step_at_limit(control))
    for name, entry in summary["signals"].items():
        if entry.get("nrms") is not None:
            mono = entry.get("nrms_monolithic")
            # normalised by the reference's range: a number without unit
            row(f"NRMS {name} (of its range)", f"{entry['nrms']:.4g}"
                + (f"  (monolithic {mono:.4g})" if mono is not None else ""))
    energy = summary["energy"]
    if energy is None:
        row("energy", "not reported by any subsystem")
    else:
        of = f" ({', '.join(energy['subsystems'])} only)" if "subsystems" in energy else ""
        row(f"energy initial / final [J]{of}", f"{_number(energy['initial'])} / {_number(energy['final'])}")
        if "reference_final" in energy:
            reference = energy["reference_final"]  # null: the reference's energy was not finite
            row("energy final, reference [J]",
                "not available (not finite)" if reference is None else f"{reference:.6g}")
        growth = energy["growth_rate_per_s"]
        row("energy growth rate, measured [1/s]", "not finite" if growth is None else f"{growth:.3g}")
    for bond, value in summary["residual_energy"].items():
        row(f"residual energy δE, bond {bond} [J]", _number(value))
    for bond, intervals in summary["residual_power_spikes"].items():
        if intervals:
            row(f"δP spikes, bond {bond} [s]", ", ".join(f"{i['start']:.3f}–{i['end']:.3f}" for i in intervals))
    row("reliable (no δP spike)", "no verdict (stability unknown)" if summary["reliable"] is None else
        "yes" if summary["reliable"] else "NO")
    if summary["correction"] is not None:
        row("work injected by correction [J]", f"{summary['correction']['work_injected']:.6g}")
        for name, point in summary["correction"]["points"].items():
            if point["adds_energy_error"]:
                row(f"correction at {name}", f"ADDS ERROR: its work {point['work_injected']:.3g} J against the energy "
                    f"error {point['energy_error']:.3g} J it was to cancel; compare with the uncorrected run")
    timing = summary["timing"]
    row("wall time [s]", f"{timing['wall_s']:.3f}")
    row("macro-steps per second", f"{timing['steps_per_s']:.0f}")
    if "step_us_median" in timing:
        row("step median / p99 [µs]", f"{timing['step_us_median']:.1f} / {timing['step_us_p99']:.1f}")
    if timing.get("realtime"):
        row("lateness median / p99 / max [µs]", f"{timing['lateness_us_median']:.1f} / "
                      f"{timing['lateness_us_p99']:.1f} / {timing['lateness_us_max']:.1f}")
        row("missed deadlines", str(timing["missed_deadlines"]))
    implicit = summary.get("implicit")
    if implicit is not None:
        row("implicit coupling", f"{implicit['method']}, {implicit['decomposition']}, k={implicit['k']}")
        runs = implicit["corrector_runs"]
        row("corrector runs mean / max", ("none" if runs["mean"] is None else f"{runs['mean']:.3g}") + f" / {runs['max']}")
        row("largest joint gap [m]", _number(implicit["max_gap"]["position"]))
        if implicit["diverged_at_s"] is not None:
            row("DIVERGED at [s]", f"{implicit['diverged_at_s']:g}")
    row("active effects", ", ".join(summary["effects"]))
    row("digest", summary["digest"][:16] + "…")
    if "recording" in summary:
        recording = summary["recording"]
        row("recording", _recording_text(recording).removeprefix("recording "))
    out.print(table)
    if "reference_note" in summary:
        out.print(summary["reference_note"])


def _growth_time_scale(summary: dict) -> str:
    """After an unstable exact verdict: the time the predicted growth takes to double the energy, against the
    run's duration, and the measured energy when it fell (a mode that starts small)."""
    doubling = summary["discrete"]["energy_doubling_time_s"]
    if doubling is None:
        return ""
    text = f"; predicted: the energy doubles every {doubling:.3g} s (the run lasts {summary['duration']:g} s)"
    energy = summary["energy"]
    growth = None if energy is None else energy["growth_rate_per_s"]
    if growth is not None and growth < 0.0:
        text += f"; measured energy falls ({growth:.3g} 1/s): the unstable mode starts small"
    return text


def _step_at_limit(control: dict) -> str:
    """Which bound an energy-controlled step sat at for most of the run, and what would move it."""
    p = control["parameters"]
    if control["at_limit"] == "min_step_size":
        return (f"smallest, {p['min_step_size']:g} s, {control['time_at_min_step']:.0%} of the run: loosen "
                f"abs_tolerance ({p['abs_tolerance']:.3g} J) or shorten manager.macro_step")
    return (f"largest, {p['max_step_size']:g} s, {control['time_at_max_step']:.0%} of the run: raise "
            f"max_step_size or tighten abs_tolerance ({p['abs_tolerance']:.3g} J)")


def _number(value: float | None) -> str:
    """A summary's number; null in the summary is a value that was not finite (its ``non_finite`` says which)."""
    return "not finite" if value is None else f"{value:.6g}"


def _recording_text(result: dict) -> str:
    if result["messages"] is None:  # the recorder process was lost (recordings.recorder.Recorder.finish)
        return f"recording {result['path']}: incomplete ({result['outcome']})"
    lost = "unknown losses" if result["lost"] is None else f"{result['lost']} lost"
    return f"recording {result['path']}: {result['messages']} messages, {lost} ({result['outcome']})"


def _wait_while_serving(live: dict) -> None:
    """After a run shown with --rerun serve: keep the web viewer up until Ctrl-C."""
    say(f"the web viewer shows the run at {live['where']}; Ctrl-C ends it")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass


def cmd_run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene, args.overrides + ([f"input={args.input}"] if args.input else []))
    unknown = sorted(set(args.external) - set(scene.subsystems))
    if unknown:
        raise UsageError(f"--external {', '.join(unknown)}: no such subsystem in scene {scene.name}; expected one of "
                         f"{', '.join(scene.subsystems)}")
    zenoh_only = [option for option, given in (("--listen", args.listen), ("--connect", args.connect),
                                               ("--external", args.external), ("--no-lowlatency", args.no_lowlatency))
                  if given] + given_security_options(args)
    if args.bus != "zenoh" and zenoh_only:
        raise UsageError(f"{', '.join(zenoh_only)} configure the Zenoh bus: add --bus zenoh")
    if args.realtime and scene.manager.step_control == "energy":
        raise UsageError("--realtime paces a fixed macro-step; manager.step_control = 'energy' varies it "
                         "(docs/step-control.md)")
    # every file the run writes is checked before it starts
    summary_path = check_output_file(args.summary, "summary") if args.summary else None
    out_path = check_table_path(args.out) if args.out else None
    record_path = args.record or scene.manager.record
    recorder = None
    if args.rerun:
        require("rerun", "the live view (--rerun)")
    if record_path or args.rerun:
        from zencosim.recordings.recorder import Recorder
        recorder = Recorder(check_output_file(record_path, "recording") if record_path else None, args.record_host_info,
                            args.rerun, _wait_while_serving if args.rerun == "serve" else None, args.record_lost, warn)
    slow = uncompiled_fmus({name: s.spec for name, s in scene.subsystems.items()})
    if slow and not args.quiet:
        warn(f"no working C compiler ($CC, else cc or gcc): each step of FMU{'s' if len(slow) > 1 else ''} "
             f"{', '.join(slow)} is a ctypes call per FMI call from Python, several times slower than one compiled "
             "call (docs/models.md, \"One call per step\"); install a C compiler for the fast path")
    n_steps = scene.manager.duration_ns // scene.manager.macro_step_ns
    bus_options = {}
    if args.bus == "zenoh":
        security = security_options(args, scene)
        security.check_endpoints("--listen", [args.listen] if args.listen else [])
        security.check_endpoints("--connect", args.connect)
        bus_options = dict(zenoh_options=ZenohOptions(not args.no_lowlatency, security), listen=args.listen,
                           external=tuple(args.external), announce=None if args.quiet else warn,
                           routers=tuple(args.connect))
    show_progress = err.is_terminal and not args.quiet
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(), TimeRemainingColumn(),
                  console=err, disable=not show_progress) as progress:
        task = progress.add_task(f"{scene.name} ({args.bus})", total=n_steps)
        try:
            record, wall_s = execute(scene, args.bus, True if args.realtime else None,
                                     lambda step: progress.update(task, completed=step), recorder=recorder,
                                     **bus_options)
        finally:  # a run that did not complete prints no summary: say what its recording holds (a lost recorder is said)
            if (recorder is not None and recorder.result is not None and recorder.result["outcome"] != "completed"
                    and recorder.lost is None):
                warn(_recording_text(recorder.result))
    summary = summarize_run(scene, record, args.bus, wall_s, recorder)
    if not args.quiet:
        _print_summary(summary)
    if summary_path:
        summary_path.write_text(json.dumps(summary, indent=2) + "\n")
    if out_path:
        written = write_tables(record_tables(record), out_path)
        if not args.quiet:
            say(f"wrote {', '.join(map(str, written))}")
            hint = _unpublished_outputs(scene)
            if hint:
                say(hint)
    if summary["diverged"]:
        at = summary["diverged_at_s"]
        what = "the implicit run's joint opened" if at is None else f"outputs not finite from t = {at:g} s"
        warn(f"the run diverged ({what}; the summary's non_finite lists the values written as null); "
             f"exit status {DIVERGED}")
        return DIVERGED
    failed = _strict_failures(summary, args.max_missed) if args.strict else []
    if failed:
        warn(f"--strict: the run completed, but {'; and '.join(failed)}; exit status {DIVERGED}")
        return DIVERGED
    return 0


def _unpublished_outputs(scene) -> str | None:
    """For a scene imported from a system description (OSP, SSP), whose FMUs publish only what their couplings
    send: one line saying which FMUs have outputs that ``--out`` does not hold and how to get them."""
    if Path(scene.path).suffix.lower() not in SYSTEM_DESCRIPTIONS:
        return None
    left = {}
    for name, sub in scene.subsystems.items():
        if hasattr(sub.spec, "published"):  # an FMU's (subsystems.models.external.model.ExternalSpec)
            coupled = {v for point in sub.spec.point_maps.values() for role in point.roles()
                       for v in point.variables(role)}
            left[name] = len(set(sub.spec.description.outputs) - set(sub.spec.published) - coupled)
    left = {name: count for name, count in left.items() if count}
    if not left:
        return None
    return (f"the tables hold the couplings' signals; not the other outputs of "
            f"{', '.join(f'{name} ({count})' for name, count in left.items())}: "
            f"--set subsystems.<name>.outputs=all adds them")


def _strict_failures(summary: dict, max_missed: float) -> list[str]:
    """What fails a completed run under ``--strict``: an unstable verdict, and a real-time run that missed more
    than ``max_missed`` of its deadlines."""
    failed = []
    if summary["stable"] is False:  # None: no verdict (no energy), which --strict does not fail
        failed.append(f"its verdict is unstable ({summary['stable_from']})")
    timing = summary["timing"]
    if timing.get("realtime") and timing["paced_steps"]:
        share = timing["missed_deadlines"] / timing["paced_steps"]
        if share > max_missed:
            failed.append(f"it missed {share:.1%} of its deadlines, more than --max-missed {max_missed:.1%}")
    return failed


def add_parsers(commands) -> None:
    run = commands.add_parser(
        "run", help="run a scene",
        **examples("zencosim run two_mass_damped                      # in process",
                   "zencosim run two_mass_damped --bus zenoh          # one process per subsystem",
                   "zencosim run four_mass --set manager.macro_step=0.002 --out results.csv --summary summary.json",
                   "zencosim run two_mass_damped --bus zenoh --record run.mcap",
                   "zencosim run two_mass_damped --realtime            # paced to the wall clock",
                   "zencosim run model.fmu --input inputs.csv --out out.csv   # one FMU alone, as fmpy simulate",
                   "zencosim run two_mass_damped --bus zenoh --listen tls/0.0.0.0:7447 --external S2 "
                   "--tls-ca ca.pem --tls-cert a.pem --tls-key a.key   # across hosts, mutual TLS"))
    add_scene_arguments(run)
    run.add_argument("--bus", choices=BUSES, default="inproc",
                     help="inproc: all subsystems in this process; zenoh: one process per subsystem over Zenoh")
    run.add_argument("--summary", metavar="FILE", help="write the run summary as JSON (keys: docs/summary.md)")
    run.add_argument("--input", metavar="FILE", help="a lone FMU's input values over time: a CSV table, time [s] "
                     "first, a column per input variable (SI), interpolated as fmpy simulate does")
    run.add_argument("--out", metavar="FILE", help="write every signal with its time (.csv, .npz, .parquet); a "
                                                   "multi-rate run writes one file per communication step")
    run.add_argument("--realtime", action="store_true", help="pace macro-steps to wall-clock deadlines")
    run.add_argument("--quiet", action="store_true", help="print nothing but errors")
    run.add_argument("--strict", action="store_true",
                     help=f"exit with status {DIVERGED}, as for a diverged run, when the run's verdict is unstable or a "
                          "real-time run missed more than --max-missed of its deadlines (default: only report them)")
    run.add_argument("--max-missed", type=share, default=Budget.missed_share, metavar="SHARE",
                     help="with --strict and --realtime: the share of missed deadlines a run may have (default "
                          f"{Budget.missed_share:g}, realtime-probe's budget)")
    run.add_argument("--listen", metavar="ENDPOINT", help="Zenoh endpoint of the manager (default: a free port on 127.0.0.1)")
    run.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                     help="a Zenoh router (zencosim router) to reach subsystems started by hand through (repeatable)")
    run.add_argument("--external", action="append", default=[], metavar="NAME",
                     help="do not start subsystem NAME: wait for 'zencosim subsystem' started by hand")
    run.add_argument("--no-lowlatency", action="store_true", help="use Zenoh's default transport instead of lowlatency")
    run.add_argument("--record", metavar="FILE", help="record every message of the run to an MCAP file "
                                                      "(default: the scene's manager.record)")
    run.add_argument("--rerun", nargs="?", const="spawn", metavar="TARGET",
                     help="show the run live in Rerun: spawn (a viewer here, the default), connect=HOST:PORT (a "
                          "viewer or 'rerun --serve-grpc' there) or serve (the web viewer at http://127.0.0.1:9090)")
    run.add_argument("--record-lost", choices=("stop", "continue"), default="stop",
                     help="when the recorder process is gone (killed, crashed): stop the run (exit status 1, the "
                          "default) or continue it unrecorded; either way one line names it (docs/recording.md)")
    run.add_argument("--record-host-info", action="store_true",
                     help="also record the host's name and the scene file's absolute path (left out by default)")
    add_security_arguments(run)
    run.set_defaults(handler=cmd_run)
