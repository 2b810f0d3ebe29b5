"""``zencosim realtime-probe``: the rates this machine sustains for a scene, paced to the wall clock."""
from __future__ import annotations

import argparse
import json

from rich.table import Table

from zencosim.cli.console import UsageError, add_scene_arguments, examples, out, say, share
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.realtime_probe import DEFAULT_DURATION_S, DEFAULT_RATES_HZ, Budget, RateResult, probe
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.run import BUSES

HEADER = ("rate [Hz]", "step [ms]", "missed", "lateness p50 [µs]", "p99 [µs]", "max [µs]", "meets budget")


def _rates(text: str) -> list[float]:
    try:
        rates = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected rates in Hz separated by commas, e.g. 250,500,1000")
    if not rates or min(rates) <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected positive rates in Hz")
    return rates


def _row(result: RateResult) -> list[str]:
    if result.skipped is not None:
        return [f"{result.rate_hz:g}", f"{result.macro_step_s * 1e3:.4g}", "—", "—", "—", "—", "not run"]
    if result.error is not None:
        return [f"{result.rate_hz:g}", f"{result.macro_step_s * 1e3:.4g}", "—", "—", "—", "—", "cannot run"]
    return [f"{result.rate_hz:g}", f"{result.macro_step_s * 1e3:.4g}", f"{result.missed_share:.2%}",
            f"{result.lateness_us_median:.1f}", f"{result.lateness_us_p99:.1f}", f"{result.lateness_us_max:.1f}",
            "yes" if result.meets else "no"]


def _say_result(result: RateResult) -> None:
    say("  " + "  ".join(f"{h}: {v}" for h, v in zip(HEADER, _row(result))))
    notes = [f"scene: {result.error}"] if result.error else [f"not run: {result.skipped}"] if result.skipped else []
    for note in notes + [f"probe set {a}" for a in result.adjusted]:
        say(f"    {note}")


def cmd_realtime_probe(args: argparse.Namespace) -> int:
    if args.p99 <= 0:
        raise UsageError("--p99 is a positive share of the macro-step")
    json_path = check_output_file(args.json, "report") if args.json else None
    budget = Budget(args.missed, args.p99)
    bus_options = {"zenoh_options": ZenohOptions(lowlatency=not args.no_lowlatency)} if args.bus == "zenoh" else {}
    if not args.quiet:
        say(f"{args.scene} on the {args.bus} bus, {args.duration:g} s per rate; budget: at most {budget.missed_share:.1%} "
            f"missed, p99 lateness at most {budget.p99_share_of_step:.0%} of the step")
    report = probe(args.scene, args.overrides, args.bus, args.rates, args.duration, budget,
                   None if args.quiet else _say_result, args.every_rate, **bus_options)
    if not args.quiet:
        table = Table(title=f"{args.scene}: paced runs on the {args.bus} bus")
        for column in HEADER:
            table.add_column(column, justify="right")
        for entry in report["rates"]:
            table.add_row(*_row(RateResult(**{**entry, "adjusted": tuple(entry["adjusted"])})))
        out.print(table)
        best = report["highest_rate_hz"]
        say(f"highest rate within the budget: {best:g} Hz" if best is not None
            else "no rate of the ladder meets the budget")
    if json_path:
        json_path.write_text(json.dumps(report, indent=2) + "\n")
    return 0


def add_parsers(commands) -> None:
    sub = commands.add_parser(
        "realtime-probe", help="run a scene paced at a ladder of rates; report lateness and the highest rate that "
                               "keeps a timing budget",
        **examples("zencosim realtime-probe two_mass_damped                       # in process",
                   "zencosim realtime-probe two_mass_damped --bus zenoh --rates 250,500,1000,2000 --json probe.json",
                   "zencosim realtime-probe two_mass_damped --missed 0 --p99 0.1  # a stricter budget"))
    add_scene_arguments(sub)
    sub.add_argument("--bus", choices=BUSES, default="inproc", help="the bus to probe (default inproc)")
    sub.add_argument("--rates", type=_rates, default=list(DEFAULT_RATES_HZ), metavar="HZ,HZ,...",
                     help=f"the ladder of rates (default {','.join(f'{r:g}' for r in DEFAULT_RATES_HZ)})")
    sub.add_argument("--duration", type=float, default=DEFAULT_DURATION_S, metavar="SECONDS",
                     help=f"how long each rate runs (default {DEFAULT_DURATION_S:g} s)")
    sub.add_argument("--missed", type=share, default=Budget.missed_share, metavar="SHARE",
                     help=f"budget: at most this share of missed deadlines (default {Budget.missed_share:g})")
    sub.add_argument("--p99", type=float, default=Budget.p99_share_of_step, metavar="SHARE",
                     help=f"budget: p99 lateness at most this share of the step (default {Budget.p99_share_of_step:g})")
    sub.add_argument("--every-rate", action="store_true",
                     help="run every rate of the ladder (default: stop at the first that misses the budget)")
    sub.add_argument("--json", metavar="FILE", help="write the report as JSON (keys: docs/realtime.md)")
    sub.add_argument("--no-lowlatency", action="store_true", help="over Zenoh: Zenoh's default transport")
    sub.add_argument("--quiet", action="store_true", help="print nothing but errors")
    sub.set_defaults(handler=cmd_realtime_probe)
