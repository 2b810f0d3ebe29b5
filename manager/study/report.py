"""The report of a study: its table as JSON and CSV, three plots, and ``study.md`` with the plots and the answer.

Files in the report folder (docs/study.md): ``study.json`` (every key documented there; values that are not
finite are written as null), ``study.csv`` (one row per point), ``error_cost.png`` (error against cost, log–log,
the Pareto front of each method), ``error_step.png`` (error against macro-step, log–log, with each method's
fitted order), ``stability.png`` (the largest stable macro-step of each method) and ``study.md``.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from zencosim.manager.results.output_files import OutputFileError
from zencosim.manager.study.grid import MACRO_STEP, method_label

FILES = ("study.json", "study.csv", "study.md", "error_cost.png", "error_step.png", "stability.png")


def check_report_folder(folder: str | Path) -> Path:
    """``folder`` once the report can be written there (created when its parent exists); checked before a study
    starts."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputFileError(f"study report {folder}: is a file; expected a folder")
    if not folder.parent.is_dir():
        raise OutputFileError(f"study report {folder}: the directory {folder.parent} does not exist")
    folder.mkdir(exist_ok=True)
    return folder


def _finite(value):
    """``value`` with every float that is not finite replaced by None (JSON has no NaN or infinity)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def write_report(study: dict, folder: Path) -> list[Path]:
    """Write every file of the report into ``folder``; returns them."""
    study = _finite(study)
    (folder / "study.json").write_text(json.dumps(study, indent=1, ensure_ascii=False) + "\n")
    _write_csv(study, folder / "study.csv")
    _plot_error_cost(study, folder / "error_cost.png")
    _plot_error_step(study, folder / "error_step.png")
    _plot_stability(study, folder / "stability.png")
    (folder / "study.md").write_text(markdown(study))
    return [folder / name for name in FILES]


def _flat(prefix: str, value) -> dict:
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in _flat(f"{prefix}.{key}" if prefix else key, item).items()}
    if isinstance(value, list):
        return {prefix: " ".join(map(str, value))}
    return {prefix: value}


def _write_csv(study: dict, path: Path) -> None:
    rows = [_flat("", {k: v for k, v in row.items() if k not in ("values", "overrides")}) for row in study["points"]]
    columns = list(dict.fromkeys(k for row in rows for k in row))
    with path.open("w", newline="") as file:
        writer = csv.DictWriter(file, columns)
        writer.writeheader()
        writer.writerows(rows)


EXTRAPOLATION = {0: "ZOH", 1: "FOH", 2: "SOH"}  # extrapolation order as the papers name it
MARKERS = "osD^vP*Xph<>"  # one per method, so that methods whose points coincide stay apart


def plot_label(values: dict) -> str:
    """A method as a plot's legend names it: ``FOH + compensator + energy correction``; settings other than the
    papers' methods as ``key=value``."""
    parts = []
    for key, value in values.items():
        if key == "manager.extrapolation":
            parts.append(EXTRAPOLATION.get(value, f"extrapolation {value}"))
        elif key == "manager.compensation":
            parts += [] if value == "none" else ["compensator" if value == "eigenstructure" else f"{value} compensator"]
        elif key == "manager.correction.enabled":
            parts += ["energy correction"] if value else []
        elif key == "manager.implicit.method":
            parts.append(value)
        else:
            parts.append(method_label({key: value}))
    return " + ".join(parts) or "as the scene"


def _labels(study: dict) -> dict[str, str]:
    """Method name → legend label (the full names when the short ones would not tell two methods apart)."""
    labels = {m["method"]: plot_label(m["values"]) for m in study["methods"]}
    return labels if len(set(labels.values())) == len(labels) else {name: name for name in labels}


def _by_method(study: dict) -> dict[str, list[dict]]:
    methods = {m["method"]: [] for m in study["methods"]}
    for row in study["points"]:
        methods[row["method"]].append(row)
    return methods


def _figure(height: float = 4.2):
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import pyplot
    return pyplot, *pyplot.subplots(figsize=(9.0, height))


def _save(pyplot, figure, axes, path: Path, legend_outside: bool = True) -> None:
    axes.grid(True, which="both", linewidth=0.3)
    if axes.get_legend_handles_labels()[0]:
        if legend_outside:  # right of the axes: it covers no point
            axes.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        else:
            axes.legend(fontsize=8)
    figure.savefig(path, dpi=90, bbox_inches="tight")
    pyplot.close(figure)


def _plain_ticks(axis, at: list[float] | None = None) -> None:
    """Tick labels of a logarithmic axis as plain numbers (20, 50, 100), not powers of ten: at ``at``, else at the
    decades and their 2, 3 and 5 multiples."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter
    if at is not None:
        axis.set_major_locator(FixedLocator(at))
        axis.set_minor_formatter(NullFormatter())
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    if at is None:
        axis.set_minor_formatter(FuncFormatter(
            lambda value, _: f"{value:g}" if round(value / 10 ** math.floor(math.log10(value))) in (2, 3, 5) else ""))


def _cost_ms(row: dict) -> float | None:
    return None if row["inproc"] is None else row["inproc"]["loop_cpu_per_s"] * 1e3


def _positive(*values: float | None) -> bool:
    """Every value a point of a log–log plot: a finite number above zero."""
    return all(v is not None and math.isfinite(v) and v > 0.0 for v in values)


def _error_bars(rows: list[dict]) -> list[list[float]] | None:
    """The rows' error bars as ``errorbar``'s ``yerr`` (below, above); None where no row has one. Below is at most
    99.9 % of the error, so that a bar wider than the error still shows on a log axis (it says: consistent with
    nearly zero)."""
    if not any(r.get("error_bar") is not None for r in rows):
        return None
    bars = [r.get("error_bar") or 0.0 for r in rows]
    return [[min(b, 0.999 * r["error"]) for b, r in zip(bars, rows)], bars]


def _plot_error_cost(study: dict, path: Path) -> None:
    pyplot, figure, axes = _figure()
    labels = _labels(study)
    plotted = False
    for i, (method, rows) in enumerate(_by_method(study).items()):
        shown = [r for r in rows if _positive(r["error"], _cost_ms(r))]
        if not shown:
            continue
        plotted = True
        style = {"color": f"C{i % 10}", "marker": MARKERS[i % len(MARKERS)]}
        axes.scatter([_cost_ms(r) for r in shown], [r["error"] for r in shown], s=22, **style)
        bars = _error_bars(shown)
        if bars is not None:
            axes.errorbar([_cost_ms(r) for r in shown], [r["error"] for r in shown], yerr=bars, fmt="none",
                          ecolor=style["color"], elinewidth=0.8, capsize=2)
        front = sorted((r for r in shown if r["pareto_in_method"]), key=_cost_ms)
        axes.plot([_cost_ms(r) for r in front], [r["error"] for r in front], markersize=4.5, label=labels[method],
                  **style)
    front = sorted((r for r in study["points"] if r["pareto"] and _positive(r["error"], _cost_ms(r))), key=_cost_ms)
    if front:
        axes.plot([_cost_ms(r) for r in front], [r["error"] for r in front], "k--", linewidth=0.9,
                  label="Pareto front of all")
    if plotted:
        axes.axhline(study["target"], color="grey", linewidth=0.8, label=f"target NRMS {study['target'] * 100:g} %")
    _log_log(axes, study, plotted, "CPU time of the in-process stepping loop per simulated second [ms]",
             "error against cost (stable points; lines: each method's Pareto front)")
    if plotted:
        _plain_ticks(axes.xaxis)
    _save(pyplot, figure, axes, path)


def _plot_error_step(study: dict, path: Path) -> None:
    pyplot, figure, axes = _figure()
    orders = {m["method"]: m["order"] for m in study["methods"]}
    labels = _labels(study)
    plotted = False
    for i, (method, rows) in enumerate(_by_method(study).items()):
        shown = sorted((r for r in rows if _positive(r["error"], r["macro_step"])), key=lambda r: r["macro_step"])
        if not shown:
            continue
        plotted = True
        order = orders[method]
        label = f"{labels[method]} (order {order:.2f})" if order is not None else labels[method]
        axes.errorbar([r["macro_step"] * 1e3 for r in shown], [r["error"] for r in shown], yerr=_error_bars(shown),
                      markersize=4.5, color=f"C{i % 10}", marker=MARKERS[i % len(MARKERS)], label=label,
                      elinewidth=0.8, capsize=2)
    _log_log(axes, study, plotted, "macro-step [ms]", "error against macro-step (stable points), fitted order")
    if plotted:
        _plain_ticks(axes.xaxis, sorted({r["macro_step"] * 1e3 for r in study["points"]}))
    _save(pyplot, figure, axes, path)


def reference_statement(study: dict) -> str:
    """What the NRMS is measured against, in words: the scene's reference, or the extrapolated one with the points
    it comes from, its observed order and its error bar."""
    described = (study.get("extrapolation") or {}).get(study["signal"])
    if described is None:
        return f"the scene's reference, {study['reference'] or 'none'}"
    if described["reason"] is not None:
        return f"none: the reference could not be extrapolated ({described['reason']})"
    steps = ", ".join(f"{h * 1e3:g}" for h in described["macro_steps"])
    order = "–" if described["order"] is None else f"{described['order']:.2f}"
    method = _labels(study).get(described["method"], described["method"])
    return (f"extrapolated to a zero macro-step from {method} at {steps} ms (Richardson; observed "
            f"order {order}); its own error, ±{described['error_bar']:.2g} as an NRMS, is in each point's error bar")


def _log_log(axes, study: dict, plotted: bool, xlabel: str, title: str) -> None:
    """Logarithmic axes with the study's error on y and its reference in the title; where nothing could be
    plotted (no stable point with an error and a cost), linear axes that say so."""
    axes.set_xlabel(xlabel)
    axes.set_ylabel(f"NRMS of {study['signal']}")
    axes.set_title(f"{study['scene']}: {title}\nreference: {reference_statement(study)}", fontsize=9)
    if plotted:
        axes.set_xscale("log")
        axes.set_yscale("log")
    else:
        axes.text(0.5, 0.5, "no stable point with an error (NRMS) and a cost to plot", ha="center", va="center",
                  transform=axes.transAxes, color="C3")


def _plot_stability(study: dict, path: Path) -> None:
    methods = study["methods"]
    pyplot, figure, axes = _figure(1.2 + 0.32 * len(methods))
    largest = [(m["largest_stable_macro_step"] or 0.0) * 1e3 for m in methods]
    axes.barh(range(len(methods)), largest, color="C0", label="largest stable macro-step of the grid")
    limits = [(i, m["stability_limit"] * 1e3) for i, m in enumerate(methods) if m["stability_limit"] is not None]
    if limits:
        axes.scatter([x for _, x in limits], [i for i, _ in limits], marker="|", s=300, color="C3",
                     label="stability limit (exact discrete analysis)")
    for i, m in enumerate(methods):
        if m["largest_stable_macro_step"] is None:
            axes.text(0.0, i, " unstable at every step of the grid", va="center", fontsize=8, color="C3")
    labels = _labels(study)
    axes.set_yticks(range(len(methods)), [labels[m["method"]] for m in methods], fontsize=8)
    steps = [r["macro_step"] * 1e3 for r in study["points"]]
    axes.set_xlabel(f"macro-step [ms] (the grid: {min(steps):g} to {max(steps):g} ms)" if steps else "macro-step [ms]")
    axes.set_title(f"{study['scene']}: largest stable macro-step per method")
    _save(pyplot, figure, axes, path)


def _ms(value: float | None) -> str:
    return "–" if value is None else f"{value * 1e3:.3g}"


def _cost_cell(inproc: dict) -> str:
    """The median cost and, when the repeats differ, their spread (fastest–slowest) [ms/s]."""
    low, high = inproc.get("loop_cpu_min_per_s"), inproc.get("loop_cpu_max_per_s")
    spread = f" ({_ms(low)}–{_ms(high)})" if low is not None and high is not None and low != high else ""
    return _ms(inproc.get("loop_cpu_per_s")) + spread


def _number(value: float | None, digits: int = 3) -> str:
    return "–" if value is None else f"{value:.{digits}g}"


def _nrms_cell(nrms: float | None, bar: float | None) -> str:
    """An NRMS and, against an extrapolated reference, its error bar."""
    return _number(nrms) + ("" if bar is None else f" ± {bar:.2g}")


def answer_table(study: dict) -> list[str]:
    """The study's answers as Markdown table lines, padded to be read as they are: per NRMS target the setting to
    take, its macro-step, its costs and its NRMS (± its error bar against an extrapolated reference), then a row
    per setting tied with it on cost; a line under the table states the tie rule when there is a tie."""
    by_key = {r["key"]: r for r in study["points"]}
    head = ["NRMS target", "cheapest setting", "macro-step [ms]", "CPU in process [ms/s] (fastest–slowest)",
            "wall over Zenoh [ms/s]", f"NRMS of {study['signal']}"]
    rows, tie_rule = [], None
    for answer in study["answers"]:
        target = f"≤ {answer['target'] * 100:g} %"
        if answer["point"] is None:
            rows.append([target, "none: no stable point of the grid meets it", "–", "–", "–", "–"])
            continue
        tied = len(answer["tied"]) > 1
        tie_rule = answer["tie_rule"] if tied else tie_rule
        for key in [answer["point"], *(k for k in answer["tied"] if k != answer["point"])]:
            row = by_key[key]
            setting = plot_label({k: v for k, v in row["values"].items() if k != MACRO_STEP})
            if tied:
                setting += (f" ({'chosen' if key == answer['point'] else 'tied on cost'}, "
                            f"{row['exchanges_per_s']:.4g} exchanges/s)")
            nrms = _nrms_cell(row["error"], row.get("error_bar"))
            zenoh = "not measured" if row["zenoh"] is None else _ms(row["zenoh"]["loop_wall_per_s"])
            rows.append([target if key == answer["point"] else "", setting, f"{row['macro_step'] * 1e3:g}",
                         _cost_cell(row["inproc"]), zenoh, nrms])
    widths = [max(len(cells[i]) for cells in [head, *rows]) for i in range(len(head))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths)) + " |" for cells in [head, *rows]]
    lines.insert(1, "| " + " | ".join("-" * w for w in widths) + " |")
    if tie_rule is not None:
        lines += ["", f"Tied: {tie_rule}."]
    return lines


def methods_table(study: dict) -> list[str]:
    """The methods of a study as Markdown table lines: order, stability, the macro-step for each target and its
    cost."""
    targets = list(study["methods"][0]["targets"]) if study["methods"] else []
    head = ["method", "fitted order", "largest stable step [ms]", "stability limit [ms]"]
    for target in targets:
        head += [f"step for NRMS ≤ {float(target) * 100:g} % [ms]", "its CPU cost [ms/s]"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for m in study["methods"]:
        cells = [m["method"], _number(m["order"]), _ms(m["largest_stable_macro_step"]), _ms(m["stability_limit"])]
        for target in targets:
            cells += [_ms(m["targets"][target]["macro_step"]), _ms(m["targets"][target]["cost_per_s"])]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def points_table(study: dict) -> list[str]:
    """Every point of a study as Markdown table lines."""
    head = ["method", "step [ms]", f"NRMS {study['signal']}", "energy error", "stable (analysis / run)",
            "CPU [ms/s] (fastest–slowest)", "wall [ms/s]", "Zenoh wall [ms/s]", "exchanges", "Pareto"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    verdict = {True: "yes", False: "no", None: "–"}
    for r in sorted(study["points"], key=lambda r: (r["method"], r["macro_step"])):
        inproc, zenoh = r["inproc"] or {}, r["zenoh"] or {}
        nrms, bar = r["nrms"].get(study["signal"]), (r.get("nrms_error_bar") or {}).get(study["signal"])
        cells = [r["method"], f"{r['macro_step'] * 1e3:g}", _nrms_cell(nrms, bar),
                 _number(r["energy_error"]),
                 f"{verdict[r['stable_predicted']]} / {verdict[r['stable_run']]}" + (" (failed)" if r["failed"] else ""),
                 _cost_cell(inproc), _ms(inproc.get("loop_wall_per_s")), _ms(zenoh.get("loop_wall_per_s")),
                 str(zenoh.get("exchanges", "–")), "yes" if r["pareto"] else ""]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def markdown(study: dict, images: str = "") -> str:
    """``study.md``: the answer, the plots (``images``: their folder relative to the Markdown file), the methods and
    every point."""
    machine, run = study["machine"], study["run"]
    load = ", ".join(f"{x:.2f}" for x in machine["load_average"])
    lines = [f"# Study of {study['scene']}", "",
             "## Answer", "", *answer_table(study), "",
             f"Reference of the NRMS: {reference_statement(study)}. Grid: "
             + "; ".join(f"`{a['key']}` = {', '.join(map(str, a['values']))}" for a in study["grid"]["axes"])
             + f" ({run['points']} points, {len(study['grid']['skipped'])} combinations that do not run skipped). "
             f"In process: {run['repeats']} runs per point (medians), {machine['workers']} workers on "
             f"{machine['cpus']} cores; over Zenoh: {run['zenoh_points']} points, {run['zenoh_repeats']} run(s) each. "
             f"Load average at the end: {load}. Cost: CPU time of the stepping loop per simulated second.", "",
             f"![error against cost]({images}error_cost.png)", "",
             f"![error against macro-step]({images}error_step.png)", "",
             f"![largest stable macro-step]({images}stability.png)", "",
             "## Methods", "", *methods_table(study), "",
             "## Points", "", *points_table(study), ""]
    if study["grid"]["skipped"]:
        lines += ["Skipped combinations:", ""]
        lines += [f"* {', '.join(f'{k}={v}' for k, v in s['values'].items())}: {s['reason']}"
                  for s in study["grid"]["skipped"]]
        lines.append("")
    return "\n".join(lines)
