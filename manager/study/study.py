"""A study: measure every point of a grid (``manager.study.grid``) in process, in parallel, one worker per core,
then the chosen points over Zenoh one at a time, and derive what the table says (``manager.study.tradeoffs``).

Every point is cached as soon as it is measured (``manager.study.cache``): a study that is run again runs only
the points it has not measured yet. The result is one dictionary, the study's JSON (docs/study.md).
"""
from __future__ import annotations

import os
import time
import warnings
from dataclasses import dataclass
from importlib.metadata import version
from typing import Callable

import numpy as np

from zencosim.manager.analysis.monolithic import monolithic_unavailable
from zencosim.manager.scene.load import Scene, SceneError, load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.study import extrapolation, tradeoffs
from zencosim.manager.study.cache import StudyCache
from zencosim.manager.study.grid import MACRO_STEP, Axis, Point, as_overrides, derived_overrides, expand
from zencosim.manager.study.measure import count_exchanges, load_signals, measure_zenoh, predicted_stability
from zencosim.manager.study.workers import measure_tasks
from zencosim.subsystems.params import Problem

ZENOH_CHOICES = ("pareto", "answers", "all", "none")  # answers: the cheapest point meeting each of TARGETS
BISECTION_TOLERANCE = 1e-3  # relative width at which the stability limit's bisection stops
TARGETS = (0.01, 0.001)  # the NRMS targets the method table answers for


@dataclass(frozen=True)
class StudyOptions:
    signal: str | None = None  # the output signal whose NRMS is the error (default: the scene's first)
    target: float = 0.01  # the NRMS the answer asks for
    repeats: int = 3  # in-process runs per point (the cost is their median)
    zenoh: str = "pareto"  # which points also run over Zenoh: the Pareto front, all, none
    zenoh_repeats: int = 1
    workers: int = 0  # in-process points run in parallel (0: one per core)


def run_study(scene: Scene, axes: list[Axis], options: StudyOptions = StudyOptions(), cache_root: str = ".zencosim-study",
              progress: Callable[[str, int, int], None] | None = None) -> dict:
    """Measure the grid ``axes`` of ``scene`` and return the study (docs/study.md); ``progress(phase, done,
    total)`` before a phase's first point (``done``: those the cache holds) and after every point (phases
    ``inproc`` and ``zenoh``)."""
    started = time.perf_counter()
    signal_name = options.signal or scene.outputs.signals[0]
    points, skipped = expand(scene, axes)
    if not points:  # every point refused (a macro-step of 1e308 s, say): the first reason, as a scene error
        raise SceneError(scene.path, [Problem("--vary", f"no point of the grid loads; the first: {skipped[0][1]}")])
    cache = StudyCache(cache_root, scene.digest, options.repeats)
    entries = {p.key: cache.read(p.key) for p in points}
    extrapolating = extrapolates(scene)
    todo = [{"key": p.key, "scene": scene.path, "overrides": list(p.overrides), "repeats": options.repeats,
             "signals_file": str(cache.signals_path(p.key)) if extrapolating else None}
            for p in points
            if entries[p.key] is None or (extrapolating and _lacks_signals(entries[p.key], cache, p.key))]
    if todo:
        cache.folder.mkdir(parents=True, exist_ok=True)
    workers = options.workers or os.cpu_count() or 1
    _measure_in_process(todo, workers, cache, entries, progress, len(points))

    rows = [_row(p, entries[p.key], signal_name) for p in points]
    extrapolated = _extrapolate(scene, rows, cache, signal_name) if extrapolating else None
    _mark_pareto(rows)
    exchanges = _exchange_counter(scene, entries, cache)
    answers = {_cheapest(rows, target, exchanges)[0] for target in TARGETS} if options.zenoh == "answers" else set()
    chosen = [r for r in rows if r["failed"] is None
              and (options.zenoh == "all" or (options.zenoh == "pareto" and r["pareto"]) or r["key"] in answers)]
    if progress is not None and chosen:
        progress("zenoh", 0, len(chosen))
    for done, row in enumerate(chosen, 1):
        entry = entries[row["key"]]
        if entry.get("zenoh") is None or entry["zenoh"]["repeats"] != options.zenoh_repeats:
            try:
                entry["zenoh"] = measure_zenoh(scene.path, tuple(row["overrides"]), options.zenoh_repeats)
            except SubsystemFailure as error:  # e.g. a subsystem process that a loaded machine starts too late
                warnings.warn(f"{scene.name}, {row['method']} at {row['macro_step']:g} s: not measured over Zenoh "
                              f"({error}); the next run of the study tries again", stacklevel=1)
                entry["zenoh"] = None
            else:
                cache.write(row["key"], entry)
        row["zenoh"] = entry["zenoh"]
        if progress is not None:
            progress("zenoh", done, len(chosen))
    methods = _methods(scene, rows)
    return {
        "scene": scene.name, "scene_path": scene.path, "scene_digest": scene.digest, "overrides": list(scene.overrides),
        "reference": next((r["reference"] for r in rows if r["reference"] is not None), None),
        "extrapolation": extrapolated,
        "signal": signal_name, "signals": list(scene.outputs.signals), "target": options.target,
        "grid": {"axes": [{"key": a.key, "values": list(a.values)} for a in axes],
                 "skipped": [{"values": v, "reason": reason} for v, reason in skipped]},
        "machine": {"cpus": os.cpu_count(), "workers": workers, "load_average": list(os.getloadavg()),
                    "zencosim": version("zencosim")},
        "points": rows,
        "methods": methods,
        "answers": [_answer(rows, target, exchanges) for target in dict.fromkeys((options.target, *TARGETS))],
        "run": {"points": len(points), "ran": len(todo), "cached": len(points) - len(todo),
                "zenoh_points": len(chosen), "repeats": options.repeats, "zenoh_repeats": options.zenoh_repeats,
                "wall_s": time.perf_counter() - started},
    }


def _measure_in_process(todo: list[dict], workers: int, cache: StudyCache, entries: dict, progress, total: int) -> None:
    done = total - len(todo)
    if progress is not None:
        progress("inproc", done, total)
    for key, measured in measure_tasks(todo, workers) if todo else ():
        entries[key] = {"inproc_point": measured}
        cache.write(key, entries[key])
        done += 1
        if progress is not None:
            progress("inproc", done, total)


def _row(point: Point, entry: dict, signal_name: str) -> dict:
    measured = entry["inproc_point"]
    inproc = measured["inproc"]
    if inproc is not None and "loop_cpu_min_per_s" not in inproc:  # cached before the spread was kept: none known
        inproc = {**inproc, "loop_cpu_min_per_s": inproc["loop_cpu_per_s"],
                  "loop_cpu_max_per_s": inproc["loop_cpu_per_s"]}
    return {"key": point.key, "method": point.method, "macro_step": point.macro_step, "values": point.values,
            "overrides": list(point.overrides), "derived": list(point.derived), **measured, "inproc": inproc,
            "nrms": dict(measured["nrms"]),  # a copy: an extrapolated reference's estimates are not the cache's
            "error": measured["nrms"].get(signal_name) if measured["stable"] else None, "error_bar": None,
            "nrms_error_bar": dict.fromkeys(measured["nrms"]),
            "exchanges_per_s": entry.get("exchanges_per_s"), "zenoh": None, "pareto": False}


def extrapolates(scene: Scene) -> bool:
    """Whether a study of ``scene`` extrapolates its reference from its own points: the scene asks for it
    (``outputs.reference = "extrapolated"``) or gives none (``"none"``, or an analytic reference that its
    subsystems do not admit), so that a study always has an error to weigh against the cost."""
    reference = scene.outputs.reference
    return (reference in ("none", "extrapolated")
            or (reference == "analytic" and monolithic_unavailable(scene) is not None))


def _lacks_signals(entry: dict, cache: StudyCache, key: str) -> bool:
    """A cached point that ran but whose output signals were not kept (measured for a scene reference)."""
    return entry["inproc_point"]["inproc"] is not None and not cache.signals_path(key).exists()


def _extrapolate(scene: Scene, rows: list[dict], cache: StudyCache, signal_name: str) -> dict:
    """Per output signal, the reference extrapolated from the stable points (``extrapolation.best_reference``): what
    it was extrapolated from, its observed order and its error bar as an NRMS; every row's NRMS against it with
    their error bars, and its ``error`` and ``error_bar`` (of ``signal_name``, stable rows)."""
    runs = {r["key"]: load_signals(str(cache.signals_path(r["key"]))) for r in rows if r["inproc"] is not None}
    described = {}
    for name in scene.outputs.signals:
        stable = {}
        for r in rows:
            if r["stable"] and runs.get(r["key"]) is not None:
                stable.setdefault(r["method"], []).append((r["macro_step"], runs[r["key"]][name]))
        found = extrapolation.best_reference(stable)
        if isinstance(found, str):
            described[name] = {"method": None, "macro_steps": None, "order": None, "error_bar": None, "reason": found}
            continue
        method, reference = found
        values = reference.reference.values
        described[name] = {"method": method, "macro_steps": list(reference.macro_steps), "order": reference.order,
                           "error_bar": reference.bar_rms / float(np.max(values) - np.min(values)), "reason": None}
        for r in rows:
            if runs.get(r["key"]) is not None:
                r["nrms"][name], r["nrms_error_bar"][name] = extrapolation.nrms_against(reference, runs[r["key"]][name])
    for r in rows:
        r["reference"] = "extrapolated"
        r["error"] = r["nrms"].get(signal_name) if r["stable"] else None
        r["error_bar"] = r["nrms_error_bar"].get(signal_name) if r["error"] is not None else None
    return described


def _error_at_most(row: dict) -> float | None:
    """The largest NRMS the point's error can be: against an extrapolated reference its estimate plus its error bar,
    so that a point meets a target only when its bar does too; else the error itself."""
    if row["error"] is None or row["error_bar"] is None:
        return row["error"]
    return row["error"] + row["error_bar"]


def _cost(row: dict) -> float | None:
    """In-process CPU time of the stepping loop per simulated second: what the run needs of a core, whatever else
    the machine runs (the wall time also counts the waits for a core)."""
    return None if row["inproc"] is None else row["inproc"]["loop_cpu_per_s"]


def _mark_pareto(rows: list[dict]) -> None:
    """``pareto``: on the front of every stable point with an error; ``pareto_in_method``: on its method's front."""
    for row in rows:
        row["pareto_in_method"] = False
    candidates = [r for r in rows if r["error"] is not None and _cost(r) is not None]
    for i in tradeoffs.pareto_front([_cost(r) for r in candidates], [r["error"] for r in candidates]):
        candidates[i]["pareto"] = True
    for method in {r["method"] for r in candidates}:
        members = [r for r in candidates if r["method"] == method]
        for i in tradeoffs.pareto_front([_cost(r) for r in members], [r["error"] for r in members]):
            members[i]["pareto_in_method"] = True


def _methods(scene: Scene, rows: list[dict]) -> list[dict]:
    """Per method: fitted order, largest stable macro-step (bisected on the exact discrete analysis where there
    is one), and the largest macro-step (with its cost) meeting each of ``TARGETS``."""
    summaries = []
    for method in dict.fromkeys(r["method"] for r in rows):
        members = sorted((r for r in rows if r["method"] == method), key=lambda r: r["macro_step"])
        steps = [r["macro_step"] for r in members]
        stable = [r["stable"] for r in members]
        fitted = [(r["macro_step"], r["error"]) for r in members if r["error"] is not None]
        summary = {"method": method, "values": {k: v for k, v in members[0]["values"].items() if k != MACRO_STEP},
                   "order": tradeoffs.fitted_order(*zip(*fitted)) if len(fitted) >= 2 else None,
                   "order_points": len(fitted),
                   "largest_stable_macro_step": tradeoffs.largest_stable_step(steps, stable),
                   "stability_limit": _stability_limit(scene, members, steps, stable),
                   "targets": {}}
        for target in TARGETS:
            h = tradeoffs.step_for_target(steps, [_error_at_most(r) for r in members], stable, target)
            at = next((r for r in members if r["macro_step"] == h), None)
            summary["targets"][f"{target:g}"] = {"macro_step": h, "cost_per_s": None if at is None else _cost(at)}
        summaries.append(summary)
    return summaries


def _stability_limit(scene: Scene, members: list[dict], steps: list[float], stable: list[bool]) -> float | None:
    """The macro-step [s] at which the exact discrete analysis turns unstable, bisected between the grid's last
    stable and first unstable step (None: no prediction for the method, or no change of verdict in the grid)."""
    bracket = tradeoffs.stability_bracket(steps, stable)
    if bracket is None or any(r["stable_predicted"] is None for r in members):
        return None
    values = {k: v for k, v in members[0]["values"].items() if k != MACRO_STEP}
    low, high = bracket
    while high - low > BISECTION_TOLERANCE * low:
        middle = round((low + high) / 2 * 1e9) * 1e-9
        if middle in (low, high):
            break
        point = {MACRO_STEP: middle, **values}
        probe = load_scene(scene.path, [*scene.overrides, *as_overrides(point), *derived_overrides(scene, point)])
        if predicted_stability(probe)[0]:
            low = middle
        else:
            high = middle
    return high


def _exchange_counter(scene: Scene, entries: dict, cache: StudyCache) -> Callable[[dict], float]:
    """Commands sent per simulated second at a point (a row), counted in an in-process run when first asked (only
    points tied on cost are) and kept in its cache entry and its row."""
    def exchanges_per_s(row: dict) -> float:
        entry = entries[row["key"]]
        if entry.get("exchanges_per_s") is None:
            point_scene = load_scene(scene.path, list(row["overrides"]))
            entry["exchanges_per_s"] = count_exchanges(point_scene) / point_scene.manager.duration
            cache.write(row["key"], entry)
        row["exchanges_per_s"] = entry["exchanges_per_s"]
        return row["exchanges_per_s"]
    return exchanges_per_s


def _cost_range(row: dict) -> tuple[float, float]:
    """The fastest and the slowest of the repeats' costs [s/s]: the spread of the measured cost."""
    return row["inproc"]["loop_cpu_min_per_s"], row["inproc"]["loop_cpu_max_per_s"]


def _cheapest(rows: list[dict], target: float, exchanges: Callable[[dict], float]) -> tuple[str | None, list[str]]:
    """The key of the stable point with an error at most ``target`` (with its error bar: ``_error_at_most``) to
    recommend, and the keys of the points tied with the cheapest on cost (``tradeoffs.answer``; None and [] when
    no point meets it)."""
    candidates = [r for r in rows if _cost(r) is not None]
    best, tied = tradeoffs.answer([_cost(r) for r in candidates], [_cost_range(r) for r in candidates],
                                  [_error_at_most(r) for r in candidates], [r["stable"] for r in candidates], target,
                                  lambda i: exchanges(candidates[i]))
    return None if best is None else candidates[best]["key"], [candidates[i]["key"] for i in tied]


def _answer(rows: list[dict], target: float, exchanges: Callable[[dict], float]) -> dict:
    """The cheapest stable setting with the signal's NRMS at most ``target``, and the points tied with it on cost
    (within the measured spread; the tie broken by ``tradeoffs.TIE_RULE``); the keys but ``target``, ``tied`` and
    ``tie_rule`` are null when no point meets the target. ``report.answer_table`` shows it."""
    best, tied = _cheapest(rows, target, exchanges)
    row = next((r for r in rows if r["key"] == best), None)
    if row is None:
        found = dict.fromkeys(("method", "macro_step", "error", "error_bar", "inproc_loop_cpu_per_s",
                               "inproc_loop_wall_per_s", "zenoh_loop_wall_per_s"))
    else:
        found = {"method": row["method"], "macro_step": row["macro_step"], "error": row["error"],
                 "error_bar": row["error_bar"], "inproc_loop_cpu_per_s": _cost(row),
                 "inproc_loop_wall_per_s": row["inproc"]["loop_wall_per_s"],
                 "zenoh_loop_wall_per_s": None if row["zenoh"] is None else row["zenoh"]["loop_wall_per_s"]}
    return {"target": target, "point": best, **found, "tied": tied, "tie_rule": tradeoffs.TIE_RULE}
