"""``zencosim analyze`` and ``zencosim stability``: design-time analysis of a linear scene (paper 000) and
stability maps of the implicit coupling methods (paper 003)."""
from __future__ import annotations

import argparse
import json
import math

from rich.markup import escape
from rich.table import Table

from zencosim.cli.console import UsageError, add_scene_arguments, examples, out, say, warn
from zencosim.extras import require
from zencosim.manager.assembly import plan_scene
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.energy_step import step_bounds

ANALYSIS_COLUMNS = {"monolithic": "monolithic", "cosim_pade": "co-sim. Padé", "cosim": "co-sim. D(s)",
                    "cosim_discrete": "co-sim. discrete", "compensated_model": "compensated D(s)",
                    "compensated": "compensated discrete"}


def _complex(value: complex, digits: int = 4) -> str:
    return f"{value.real:.{digits}f} {'+' if value.imag >= 0 else '-'} {abs(value.imag):.{digits}f}j"


def _print_verdicts(report: dict) -> None:
    """The spectral radius of each exact discrete scheme and the largest stable macro-step (uncompensated)."""
    verdicts = Table(title="stability of the exact discrete scheme")
    verdicts.add_column("")
    verdicts.add_column("spectral radius ρ", justify="right")
    verdicts.add_column("energy growth 2 ln ρ / T [1/s]", justify="right")
    verdicts.add_column("verdict")
    for key in ("uncompensated", "compensated"):
        if report["spectral_radius"][key] is not None:
            growth = report["growth_rate_per_s"][key]  # None: ρ = 0
            verdicts.add_row(key, f"{report['spectral_radius'][key]:.12f}", f"{-math.inf if growth is None else growth:.4g}",
                             "stable" if report["stable"][key] else "[bold red]UNSTABLE[/]")
    out.print(verdicts)
    step = report["largest_stable_step"]
    low, high = step["largest_stable"], step["smallest_unstable"]
    if low is None:
        bracket = "unstable at every step tried"
    elif high is None:
        bracket = f"stable at every step tried, up to {low:.9g} s"
    else:
        bracket = (f"{low:.9g} s (unstable at {high:.9g} s; bisection to {step['relative_tolerance']:g} relative, "
                   "micro-steps per step kept)")
    out.print(f"largest stable macro-step, uncompensated: {bracket}"
              + (f"; {step['unanalysable']} steps not analysable, counted unstable" if step["unanalysable"] else ""))


def _print_identified(result) -> None:
    """How each subsystem was identified, the verdicts and the largest stable step (no monolithic model)."""
    report = result.to_dict()
    interface = report["interface"]
    out.print(f"[bold]{escape(result.scene.name)}[/]: {interface['extrapolation']}, "
              f"T_s = {interface['macro_step']:g} s, exact discrete scheme of identified subsystems")
    table = Table(title="identified subsystems (discrete-time, at the communication step, about the initial point)")
    for column in ("subsystem", "method", "role", "order", "fit residual", "nonlinearity", "linearisation",
                   "probes × steps"):
        table.add_column(column, justify="right" if column in ("order", "fit residual", "nonlinearity") else "left")
    for name, entry in report["identification"].items():
        table.add_row(escape(name), entry["method"], entry["role"], str(entry["order"]), f"{entry['fit_residual']:.2g}",
                      f"{entry['nonlinearity']:.2g}", entry["linearisation"], f"{entry['probes']} × {entry['steps']}")
    out.print(table)
    poles = Table(title="poles of the exact discrete scheme, ln(μ) / T [1/s]")
    poles.add_column("λ [1/s]", justify="right")
    poles.add_column("|μ|", justify="right")
    for re, im in sorted(report["poles"]["cosim_discrete"], key=lambda pair: -pair[0]):
        poles.add_row(_complex(complex(re, im)), f"{math.exp(re * interface['period']):.12f}")
    out.print(poles)
    _print_verdicts(report)
    out.print(escape(report["not_compensated"]))


def _print_analysis(result) -> None:
    """Table 3 of paper 000 for every pole pair, then the compensator (Table 4) and the verdicts."""
    report = result.to_dict()
    interface = report["interface"]
    out.print(f"[bold]{escape(result.scene.name)}[/]: {interface['extrapolation']}, T_s = {interface['macro_step']:g} s, "
              f"Padé order {interface['pade_order']}")
    if result.scene.manager.scheme == "gauss-seidel":
        plan, _ = plan_scene(result.scene)
        order = ", ".join(plan.subsystems[i].name for stage in plan.stages for i in stage)
        out.print(escape(f"Gauss–Seidel, stepping {order}: the co-sim. discrete column is its exact scheme; the "
                         "Padé and D(s) columns model paper 000's Jacobi scheme"))
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
    _print_verdicts(report)
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
    from zencosim.manager.analysis.scene_analysis import IdentifiedAnalysis, analyze_scene, write_pole_map
    json_path = check_output_file(args.json, "analysis") if args.json else None
    plot_path = check_output_file(args.plot, "pole map", (".png",)) if args.plot else None
    if plot_path:
        require("plots", f"the pole map {plot_path}")
    scene = load_scene(args.scene, args.overrides)
    result = analyze_scene(scene, args.architecture)
    (_print_identified if isinstance(result, IdentifiedAnalysis) else _print_analysis)(result)
    control = scene.manager.energy_control
    if scene.manager.step_control == "energy":  # the analysis is of one fixed macro-step: say which
        longest = step_bounds(control, scene.manager.macro_step_ns)[2] * 1e-9
        warn(f"manager.step_control = 'energy': this is the scheme at a fixed macro-step of "
             f"{scene.manager.macro_step:g} s; the run varies it up to {longest:g} s (analyse that "
             f"one with --set manager.macro_step={longest:g} --set manager.step_control=fixed)")
    if json_path:
        json_path.write_text(json.dumps(result.to_dict(), indent=2) + "\n")
    if plot_path:
        write_pole_map(result, plot_path)
    return 0


METHOD_OPTIONS = {"baumgarte": ("mu_bar", "index"), "weighted-multiplier": ("a", "b"), "projection": ()}


def cmd_stability(args: argparse.Namespace) -> int:
    """Spectral-radius map of an implicit coupling method on the test model (paper 003 §3, Eq. 71)."""
    from zencosim.compensation.implicit.coupling_laws import Baumgarte, WeightedMultiplier, resolve_method
    from zencosim.compensation.implicit.stability_map import stability_map, write_stability_map
    misplaced = [f"--{name.replace('_', '-')}" for method, names in METHOD_OPTIONS.items() if method != args.method
                 for name in names if getattr(args, name) is not None]
    if misplaced:
        raise UsageError(f"not options of the {args.method} method: {', '.join(misplaced)}")
    png = check_output_file(args.out, "stability map", (".png",))
    json_path = check_output_file(args.json, "stability map data") if args.json else None
    require("plots", f"the stability map {png}")
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
        raise UsageError(str(error)) from None
    png, json_path = write_stability_map(result, png, json_path)
    say(result.describe().replace("\n", "; "))
    say(f"stable (rho <= 1) at {int(result.stable.sum())} of {result.stable.size} grid points; "
        f"max rho = {result.spectral_radius.max():.6g}; wrote {png} and {json_path}")
    return 0


def add_parsers(commands) -> None:
    analyze = commands.add_parser(
        "analyze", help="eigenstructure of a linear scene: modelled, exact discrete, compensated",
        **examples("zencosim analyze two_mass_undamped",
                   "zencosim analyze four_mass --set manager.macro_step=0.004 --json poles.json --plot poles.png"))
    add_scene_arguments(analyze)
    analyze.add_argument("--architecture", choices=("full_feedback", "without_exchanged_motion", "rank_one"),
                         default="full_feedback", help="compensator architecture (paper 000 §4.3); the runtime uses full_feedback")
    analyze.add_argument("--json", metavar="FILE", help="write the analysis as JSON (keys: docs/compensation.md)")
    analyze.add_argument("--plot", metavar="FILE", help="write the pole map as PNG (zencosim[plots])")
    analyze.set_defaults(handler=cmd_analyze)

    stability = commands.add_parser(
        "stability", help="spectral-radius map of an implicit coupling method on paper 003's test model (PNG and JSON)",
        **examples("zencosim stability --method weighted-multiplier --decomposition force-force --k 2 --out map.png",
                   "zencosim stability --method baumgarte --mu-bar 0.5 --decomposition force-displacement --k 1 "
                   "--out baumgarte.png"))
    stability.add_argument("--method", required=True, choices=tuple(METHOD_OPTIONS))
    stability.add_argument("--decomposition", required=True,
                           choices=("force-force", "force-displacement", "displacement-displacement"))
    stability.add_argument("--k", type=int, required=True, choices=(0, 1, 2), help="degree of the Lagrange polynomials")
    stability.add_argument("--grid", type=int, default=41, metavar="N", help="N x N points (default 41)")
    stability.add_argument("--out", required=True, metavar="PNG", help="the map as a PNG plot (zencosim[plots])")
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
