"""The ``zencosim`` command line.

Exit status: 0 success, 1 a run failed (a subsystem died, stopped answering or reported an error) or
a recording did not verify, 2 bad input (scene, overrides, arguments, recording file), 130 interrupted
(SIGINT or SIGTERM).
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from zencosim.manager.assembly import plan_scene
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.run import BUSES, run_scene
from zencosim.manager.scene.load import SceneError, bundled_scene_names, load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.wire.protocol import ProtocolError
from zencosim.recordings import RecordingError

out = Console()
err = Console(stderr=True)


def _add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="a bundled scene name (see 'zencosim scenes') or a path to a TOML scene")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scalar of the scene, e.g. --set manager.macro_step=0.004 (repeatable)")


def cmd_scenes(args: argparse.Namespace) -> int:
    table = Table(title="bundled scenes")
    table.add_column("scene")
    table.add_column("description")
    for name in bundled_scene_names():
        table.add_row(name, load_scene(name).description)
    out.print(table)
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene, args.overrides)
    plan, _ = plan_scene(scene)
    out.print(f"[bold]scene {escape(scene.name)}[/]: valid — {escape(scene.description)}")
    out.print(f"{plan.n_ticks} macro-steps of {scene.manager.macro_step:g} s, scheme {scene.manager.scheme}, "
              f"extrapolation order {scene.manager.extrapolation}; bonds: {', '.join(b.name for b in plan.bonds) or 'none'}")
    if scene.manager.implicit is not None:
        joints = ", ".join(f"{c.name} ({c.settings.decomposition})" for c in scene.couplings.values())
        out.print(escape(f"implicit coupling: {scene.manager.implicit.coupling_method()}, k = {scene.manager.extrapolation}, "
                         f"up to {scene.manager.implicit.max_iterations} corrector run(s); joint {joints}"))
    for sub in plan.subsystems:
        settings = scene.subsystems[sub.name].settings
        out.print(f"[bold]{sub.name}[/]: {settings.model}, {settings.integrator}, micro-step {settings.micro_step:g} s, "
                  f"communication step {sub.ratio * scene.manager.macro_step:g} s")
        out.print(escape(f"  inputs:  {', '.join(f'{p.name} [{p.unit}]' for p in sub.inputs) or 'none'}"))
        out.print(escape("  outputs: " + ", ".join(f"{p.name} [{p.unit}]" + (" (feedthrough)" if p.feedthrough else "")
                                                for p in sub.outputs)))
        out.print(escape(f"  effects: {', '.join(sub.effects) or 'none'}"))
    return 0


def _print_summary(summary: dict) -> None:
    table = Table(title=f"{summary['scene']} on the {summary['bus']} bus: {summary['steps']} macro-steps of "
                        f"{summary['macro_step']:g} s")
    table.add_column("quantity")
    table.add_column("value", justify="right")

    def row(label: str, value: str) -> None:
        table.add_row(escape(label), escape(value))

    row("stable", "yes" if summary["stable"] else "NO (energy grows)")
    for name, entry in summary["signals"].items():
        if entry.get("nrms") is not None:
            mono = entry.get("nrms_monolithic")
            row(f"NRMS {name} [{entry['unit']}]", f"{entry['nrms']:.4g}" + (f"  (monolithic {mono:.4g})" if mono is not None else ""))
    energy = summary["energy"]
    row("energy initial / final [J]", f"{energy['initial']:.6g} / {energy['final']:.6g}")
    if "reference_final" in energy:
        row("energy final, reference [J]", f"{energy['reference_final']:.6g}")
    row("energy growth rate [1/s]", f"{energy['growth_rate_per_s']:.3g}")
    for bond, value in summary["residual_energy"].items():
        row(f"residual energy δE, bond {bond} [J]", f"{value:.6g}")
    for bond, intervals in summary["residual_power_spikes"].items():
        if intervals:
            row(f"δP spikes, bond {bond} [s]", ", ".join(f"{i['start']:.3f}–{i['end']:.3f}" for i in intervals))
    row("reliable (no δP spike)", "yes" if summary["reliable"] else "NO")
    if summary["correction"] is not None:
        row("work injected by correction [J]", f"{summary['correction']['work_injected']:.6g}")
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
        row("corrector runs mean / max", f"{implicit['corrector_runs']['mean']:.3g} / {implicit['corrector_runs']['max']}")
        row("largest joint gap [m]", f"{implicit['max_gap']['position']:.3g}")
        if implicit["diverged_at_s"] is not None:
            row("DIVERGED at [s]", f"{implicit['diverged_at_s']:g}")
    row("active effects", ", ".join(summary["effects"]))
    row("digest", summary["digest"][:16] + "…")
    if "recording" in summary:
        recording = summary["recording"]
        row("recording", f"{recording['path']}: {recording['messages']} messages, {recording['lost']} lost")
    out.print(table)
    if "reference_note" in summary:
        out.print(summary["reference_note"])


def _recording_text(result: dict) -> str:
    lost = "unknown losses" if result["lost"] is None else f"{result['lost']} lost"
    return f"recording {result['path']}: {result['messages']} messages, {lost} ({result['outcome']})"


def cmd_run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene, args.overrides)
    record_path = args.record or scene.manager.record
    recorder = None
    if record_path:
        from zencosim.recordings.recorder import Recorder
        recorder = Recorder(record_path)
    options = ZenohOptions(lowlatency=not args.no_lowlatency)
    n_steps = scene.manager.duration_ns // scene.manager.macro_step_ns
    bus_options = {}
    if args.bus == "zenoh":
        bus_options = dict(zenoh_options=options, listen=args.listen, external=tuple(args.external),
                           announce=None if args.quiet else lambda text: err.print(text, highlight=False, soft_wrap=True))
    show_progress = err.is_terminal and not args.quiet
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(), TimeRemainingColumn(),
                  console=err, disable=not show_progress) as progress:
        task = progress.add_task(f"{scene.name} ({args.bus})", total=n_steps)
        try:
            summary = run_scene(scene, args.bus, True if args.realtime else None,
                                lambda step: progress.update(task, completed=step), recorder=recorder, **bus_options)
        finally:  # a run that did not complete prints no summary: say what its recording holds
            if recorder is not None and recorder.result is not None and recorder.result["outcome"] != "completed":
                err.print(escape(_recording_text(recorder.result)), highlight=False, soft_wrap=True)
    if not args.quiet:
        _print_summary(summary)
    if args.summary:
        Path(args.summary).write_text(json.dumps(summary, indent=2) + "\n")
    return 0


ANALYSIS_COLUMNS = {"monolithic": "monolithic", "cosim_pade": "co-sim. Padé", "cosim": "co-sim. D(s)",
                    "cosim_discrete": "co-sim. discrete", "compensated_model": "compensated D(s)",
                    "compensated": "compensated discrete"}


def _complex(value: complex, digits: int = 4) -> str:
    return f"{value.real:.{digits}f} {'+' if value.imag >= 0 else '-'} {abs(value.imag):.{digits}f}j"


def _print_analysis(result) -> None:
    """Table 3 of paper 000 for every pole pair, then the compensator (Table 4) and the verdicts."""
    report = result.to_dict()
    interface = report["interface"]
    out.print(f"[bold]{escape(result.scene.name)}[/]: {interface['extrapolation']}, T_s = {interface['macro_step']:g} s, "
              f"Padé order {interface['pade_order']}")
    systems = result.systems()
    for i in range(0, len(result.monolithic.poles), 2):
        table = Table(title=f"λ{i + 1},{i + 2}")
        table.add_column("")
        for key in systems:
            table.add_column(ANALYSIS_COLUMNS[key], justify="right")
        modal = {key: report["modal"][key] for key in systems}
        table.add_row("λ [1/s]", *(_complex(pairs.poles[i]) for pairs in systems.values()))
        table.add_row("ω_n [rad/s]", *(f"{modal[key]['omega_n'][i]:.4f}" for key in systems))
        table.add_row("e_ω [%]", *(f"{modal[key]['e_omega_percent'][i]:.4f}" for key in systems))
        table.add_row("ξ", *(f"{modal[key]['xi'][i]:.5f}" for key in systems))
        table.add_row("e_ξ", *(f"{modal[key]['e_xi'][i]:.5f}" for key in systems))
        for m, name in enumerate(report["dof_names"]):
            table.add_row(escape(f"w[{name}]"), *(_complex(pairs.shapes[m, i]) for pairs in systems.values()))
        out.print(table)
    verdicts = Table(title="stability of the exact discrete scheme")
    verdicts.add_column("")
    verdicts.add_column("spectral radius ρ", justify="right")
    verdicts.add_column("energy growth 2 ln ρ / T [1/s]", justify="right")
    verdicts.add_column("verdict")
    for key in ("uncompensated", "compensated"):
        if report["spectral_radius"][key] is not None:
            verdicts.add_row(key, f"{report['spectral_radius'][key]:.12f}", f"{report['growth_rate_per_s'][key]:.4g}",
                             "stable" if report["stable"][key] else "[bold red]UNSTABLE[/]")
    out.print(verdicts)
    if report["not_compensated"]:
        out.print(f"no compensator: {escape(report['not_compensated'])}")
        return
    ranks, gains, correction = report["assignability"], report["gains"], report["correction"]
    table = Table(title=f"compensator: {ranks['architecture']}")
    table.add_column("")
    table.add_column("value")
    table.add_row("rank L / rank [L n] (Eq. 33)", f"{ranks['rank_L']} / {ranks['rank_Ln']}")
    for kind in "dfg":
        table.add_row(f"{kind} (Eq. 22)", "{" + "  ".join(f"{v:.4g}" for v in gains[kind]) + "}")
    table.add_row("directions used / residual", f"{gains['rank_used']} / {gains['residual']:.3g}")
    table.add_row("latent roots, max Re (Padé) [1/s]", f"{gains['latent_abscissa']:.4g} (margin {-gains['margin']:.4g})")
    table.add_row("discrete correction", f"{correction['iterations']} designs, max |ν - λ| = {correction['pole_error']:.2g} 1/s")
    out.print(table)


def cmd_analyze(args: argparse.Namespace) -> int:
    from zencosim.manager.analysis.scene_analysis import analyze_scene, write_pole_map
    result = analyze_scene(load_scene(args.scene, args.overrides), args.architecture)
    _print_analysis(result)
    if args.json:
        Path(args.json).write_text(json.dumps(result.to_dict(), indent=2) + "\n")
    if args.plot:
        write_pole_map(result, args.plot)
    return 0


def cmd_stability(args: argparse.Namespace) -> int:
    """Spectral-radius map of an implicit coupling method on the test model (paper 003 §3, Eq. 71)."""
    from zencosim.compensation.implicit.coupling_laws import Baumgarte, WeightedMultiplier, resolve_method
    from zencosim.compensation.implicit.stability_map import stability_map, write_stability_map
    options = {"baumgarte": ("mu_bar", "index"), "weighted-multiplier": ("a", "b"), "projection": ()}
    misplaced = [f"--{name.replace('_', '-')}" for method, names in options.items() if method != args.method
                 for name in names if getattr(args, name) is not None]
    if misplaced:
        err.print(f"[bold red]error:[/] not options of the {args.method} method: {', '.join(misplaced)}", soft_wrap=True)
        return 2
    if args.method == "baumgarte":
        method = Baumgarte.from_mu(1.0 if args.mu_bar is None else args.mu_bar, 1 if args.index is None else args.index)
    elif args.method == "weighted-multiplier":
        method = WeightedMultiplier(1.0 if args.a is None else args.a, 1.0 if args.b is None else args.b)
    else:
        method = resolve_method(args.method)
    try:
        result = stability_map(method, args.decomposition, args.k, alpha_m21=args.alpha_m21,
                               alpha_lambda_r21=args.alpha_lambda_r21, alpha_lambda_i21=args.alpha_lambda_i21,
                               grid_points=args.grid, lambda_r1_range=tuple(args.lambda_r1),
                               lambda_i1_range=tuple(args.lambda_i1))
    except ValueError as error:
        err.print(f"[bold red]error:[/] {escape(str(error))}", highlight=False, soft_wrap=True)
        return 2
    png, json_path = write_stability_map(result, args.out, args.json)
    out.print(escape(result.describe().replace("\n", "; ")), highlight=False)
    out.print(f"stable (rho <= 1) at {int(result.stable.sum())} of {result.stable.size} grid points; "
              f"max rho = {result.spectral_radius.max():.6g}; wrote {escape(str(png))} and {escape(str(json_path))}")
    return 0


def cmd_subsystem(args: argparse.Namespace) -> int:
    from zencosim.subsystems.process.host import serve
    scene = load_scene(args.scene, args.overrides)
    return serve(scene, args.name, args.connect, args.run_id, ZenohOptions(lowlatency=not args.no_lowlatency),
                 args.wait, args.listen)


def cmd_replay(args: argparse.Namespace) -> int:
    from zencosim.recordings.reader import read_recording
    if not (args.rrd or args.spawn or args.verify):
        raise RecordingError(f"replay {args.recording}: nothing to do; give --rrd FILE, --spawn or --verify")
    recording = read_recording(args.recording)
    if recording.truncated:
        err.print(escape(f"{recording.path}: {recording.truncated}; replaying what it holds"), highlight=False)
    status = 0
    if args.rrd or args.spawn:
        from zencosim.recordings.rerun_replay import replay_in_rerun
        replay_in_rerun(recording, args.rrd, args.spawn)
        if args.rrd:
            out.print(escape(f"wrote {args.rrd}"), highlight=False)
    if args.verify:
        from zencosim.recordings.verify import verify
        result = verify(recording)
        compared = sum(result.compared.values())
        if result.divergence is not None:
            out.print(escape(f"verify FAILED: first divergence at {result.divergence}"), highlight=False)
        elif not result.passed:
            out.print(escape(f"verify FAILED: {result.note}"), highlight=False)
        else:
            out.print(escape(f"verify passed: {compared} messages bit-identical to a re-run, up to step "
                             f"{result.last_step}" + (f" ({result.note})" if result.note else "")), highlight=False)
        status = 0 if result.passed else 1
    return status


def cmd_inspect(args: argparse.Namespace) -> int:
    from zencosim.recordings.reader import describe, read_recording
    info = describe(read_recording(args.recording))
    table = Table(title=f"{info['file']}: scene {info['scene']}, run {info['run_id']} ({info['bus']} bus, "
                        f"host {info['host']}, zencosim {info['zencosim']})")
    table.add_column("channel")
    table.add_column("messages", justify="right")
    table.add_column("values")
    for topic, channel in info["channels"].items():
        table.add_row(escape(topic), str(channel["messages"]), escape(channel["values"]))
    out.print(table)
    out.print(escape(f"started {info['started']}; steps {info['steps']}, {info['duration_s']:g} s simulated; "
                     f"outcome: {info['outcome']}; lost: {'unknown' if info['lost'] is None else info['lost']}"),
              highlight=False)
    if info["truncated"]:
        out.print(escape(f"incomplete: {info['truncated']}"), highlight=False)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="zencosim", description="Distributed real-time co-simulation over Zenoh")
    commands = parser.add_subparsers(dest="command", required=True)

    commands.add_parser("scenes", help="list the bundled scenes").set_defaults(handler=cmd_scenes)

    check = commands.add_parser("check", help="validate a scene and show what it builds")
    _add_scene_arguments(check)
    check.set_defaults(handler=cmd_check)

    run = commands.add_parser("run", help="run a scene")
    _add_scene_arguments(run)
    run.add_argument("--bus", choices=BUSES, default="inproc",
                     help="inproc: all subsystems in this process; zenoh: one process per subsystem over Zenoh")
    run.add_argument("--summary", metavar="FILE", help="write the run summary as JSON")
    run.add_argument("--realtime", action="store_true", help="pace macro-steps to wall-clock deadlines")
    run.add_argument("--quiet", action="store_true", help="print nothing but errors")
    run.add_argument("--listen", metavar="ENDPOINT", help="Zenoh endpoint of the manager (default: a free port on 127.0.0.1)")
    run.add_argument("--external", action="append", default=[], metavar="NAME",
                     help="do not start subsystem NAME: wait for 'zencosim subsystem' started by hand")
    run.add_argument("--no-lowlatency", action="store_true", help="use Zenoh's default transport instead of lowlatency")
    run.add_argument("--record", metavar="FILE", help="record every message of the run to an MCAP file "
                                                      "(default: the scene's manager.record)")
    run.set_defaults(handler=cmd_run)

    analyze = commands.add_parser("analyze", help="eigenstructure of a linear scene: modelled, exact discrete, compensated")
    _add_scene_arguments(analyze)
    analyze.add_argument("--architecture", choices=("full_feedback", "without_exchanged_motion", "rank_one"),
                         default="full_feedback", help="compensator architecture (paper 000 §4.3); the runtime uses full_feedback")
    analyze.add_argument("--json", metavar="FILE", help="write the analysis as JSON (keys: docs/compensation.md)")
    analyze.add_argument("--plot", metavar="FILE", help="write the pole map as PNG")
    analyze.set_defaults(handler=cmd_analyze)

    stability = commands.add_parser(
        "stability", help="spectral-radius map of an implicit coupling method on paper 003's test model (PNG and JSON)")
    stability.add_argument("--method", required=True, choices=("baumgarte", "weighted-multiplier", "projection"))
    stability.add_argument("--decomposition", required=True,
                           choices=("force-force", "force-displacement", "displacement-displacement"))
    stability.add_argument("--k", type=int, required=True, choices=(0, 1, 2), help="degree of the Lagrange polynomials")
    stability.add_argument("--grid", type=int, default=41, metavar="N", help="N x N points (default 41)")
    stability.add_argument("--out", required=True, metavar="PNG", help="the map as a PNG plot")
    stability.add_argument("--json", metavar="FILE", help="the numbers as JSON (default: PNG path with .json)")
    stability.add_argument("--mu-bar", type=float, help="Baumgarte: beta_bar = 2 mu_bar, gamma_bar = mu_bar^2 (default 1)")
    stability.add_argument("--index", type=int, choices=(1, 2, 3), help="Baumgarte: 1, 2 (gamma = 0), 3 (beta = gamma = 0)")
    stability.add_argument("--a", type=float, help="weighted multiplier: weight of the velocity level (default 1)")
    stability.add_argument("--b", type=float, help="weighted multiplier: weight of the acceleration level (default 1)")
    stability.add_argument("--alpha-m21", type=float, default=1.0, help="mass ratio m2/m1 (default 1)")
    stability.add_argument("--alpha-lambda-r21", type=float, default=1.0, help="damping ratio of Eq. 71 (default 1)")
    stability.add_argument("--alpha-lambda-i21", type=float, default=1.0, help="frequency ratio of Eq. 71 (default 1)")
    stability.add_argument("--lambda-r1", type=float, nargs=2, default=(-2.0, 0.0), metavar=("FROM", "TO"),
                           help="range of the real part of mass 1's eigenvalue (default -2 0)")
    stability.add_argument("--lambda-i1", type=float, nargs=2, default=(0.0, 2.0), metavar=("FROM", "TO"),
                           help="range of the imaginary part (default 0 2)")
    stability.set_defaults(handler=cmd_stability)

    sub = commands.add_parser("subsystem", help="serve one subsystem of a scene over Zenoh (for runs across hosts)")
    _add_scene_arguments(sub)
    sub.add_argument("name", help="the subsystem to serve")
    sub.add_argument("--connect", action="append", required=True, metavar="ENDPOINT",
                     help="Zenoh endpoint of the manager, e.g. tcp/192.0.2.10:7447")
    sub.add_argument("--listen", default="tcp/127.0.0.1:0", metavar="ENDPOINT",
                     help="where the other processes of the run reach this one (default: a free loopback port; "
                          "across hosts this host's address, e.g. tcp/192.0.2.11:7448)")
    sub.add_argument("--run-id", help="the run to join (default: the one run that waits for this subsystem)")
    sub.add_argument("--wait", type=float, default=30.0, metavar="SECONDS", help="how long to look for the run")
    sub.add_argument("--no-lowlatency", action="store_true", help="use Zenoh's default transport instead of lowlatency")
    sub.set_defaults(handler=cmd_subsystem)

    replay = commands.add_parser("replay", help="replay a recording in Rerun, or verify it by re-running its scene")
    replay.add_argument("recording", help="an MCAP file written by 'zencosim run --record'")
    replay.add_argument("--rrd", metavar="FILE", help="write a Rerun recording (.rrd)")
    replay.add_argument("--spawn", action="store_true", help="open a Rerun viewer with the recording")
    replay.add_argument("--verify", action="store_true",
                        help="re-run the embedded scene in process and compare every channel bit for bit")
    replay.set_defaults(handler=cmd_replay)

    inspect = commands.add_parser("inspect", help="show what a recording holds")
    inspect.add_argument("recording", help="an MCAP file written by 'zencosim run --record'")
    inspect.set_defaults(handler=cmd_inspect)
    return parser


def _interrupt(signum: int, _frame) -> None:
    """SIGTERM ends a run like Ctrl-C: subsystems are stopped and the recording is finished."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return args.handler(args)
    except (SceneError, RecordingError) as error:
        err.print(f"[bold red]error:[/] {escape(str(error))}", highlight=False, soft_wrap=True)
        return 2
    except (SubsystemFailure, ProtocolError) as error:
        err.print(f"[bold red]run failed:[/] {escape(str(error))}", highlight=False, soft_wrap=True)
        return 1
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
