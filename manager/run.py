"""One run of a scene: build, plan, drive the scheme on a bus, compare with the references, summarise.

A run may be recorded: the caller passes a recorder (``recordings.recorder.Recorder``; the manager
only knows the :class:`RunRecorder` interface), the scheme then reports its status after every
macro-step, and the recorder sees every message through a tap on the manager's replica — the
in-process one, or the one that follows a Zenoh run, which holds every command, reply and status.
"""
from __future__ import annotations

import time
from typing import Callable, Protocol

import numpy as np

from zencosim.manager.analysis.monolithic import monolithic_unavailable
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.bus.watchdog import model_watch
from zencosim.manager.bus.zenoh_bus import ZenohBus
from zencosim.manager.bus.zenoh_session import ZenohOptions, new_run_id
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.results.reference import (
    ReferenceFailed,
    analytic_reference,
    monolithic_reference,
    solve_ivp_reference,
)
from zencosim.manager.results.summary import summarize
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import Exchange, RunRecord
from zencosim.manager.scheme.window import spill_for
from zencosim.manager.wire.status import StatusReport

BUSES = ("inproc", "zenoh")


class RunRecorder(Protocol):
    """What a run needs from a recorder."""

    result: dict | None  # the recorder's end record, once finished

    def start(self, scene: Scene, plan: Plan, status: StatusReport, bus: str, run_id: str, realtime: bool) -> None:
        """Start recording."""

    def exchange(self, replies: dict[str, bytes] | None, request: Exchange | None) -> None:
        """What the replica went through: the replica's ``Tap`` (``manager.scheme.replica``)."""

    def finish(self, outcome: str) -> dict:
        """Close the recording (what the tap handed over is what was published)."""

    def close(self) -> None:
        """Release the recorder, finished or not."""


def _outcome(error: BaseException) -> str:
    return "interrupted" if isinstance(error, KeyboardInterrupt) else f"failed: {error}"


def execute(scene: Scene, bus: str = "inproc", realtime: bool | None = None,
            progress: Callable[[int], None] | None = None, zenoh_options: ZenohOptions = ZenohOptions(),
            listen: str | None = None, external: tuple[str, ...] = (),
            announce: Callable[[str], None] | None = None,
            recorder: RunRecorder | None = None, routers: tuple[str, ...] = (),
            keep: bool | None = None) -> tuple[RunRecord, float]:
    """Run the co-simulation; return the record and the wall-clock time [s] of the stepping loop.

    With ``recorder``, the recording is finished before this returns or raises (its ``result`` says
    how the run ended) and released in any case. ``keep``: hold the record's arrays in memory (True), spill
    them to temporary files as the run goes (False), or spill those of a run longer than ``KEEP_STEPS``
    macro-steps (None; ``manager.scheme.window``)."""
    if bus not in BUSES:
        raise ValueError(f"unknown bus {bus!r}; expected one of {', '.join(BUSES)}")
    realtime = scene.manager.realtime if realtime is None else realtime
    watch = model_watch()  # a watched run marks each constructor (manager.bus.watchdog)
    watch.start(list(scene.subsystems), scene.manager.timeout)
    plan, subsystems = plan_scene(scene, watch.constructing)
    # the status's lateness is measured where the steps are paced: in process only (over Zenoh each
    # subsystem paces its own replica and reports its lateness at the end)
    status = StatusReport(plan, realtime and bus == "inproc") if recorder is not None else None
    run_id = new_run_id()
    started = False
    try:
        if recorder is not None:
            recorder.start(scene, plan, status, bus, run_id, realtime)
            started = True
        tap = recorder
        if bus == "inproc":
            # the scheme calls the subsystems itself and hands the tap the messages (manager.bus.inproc)
            scheme = make_scheme(scene, plan, realtime, None, progress, status, keep=keep, cpu=0,
                                 direct=DirectCalls(plan, subsystems), tap=tap)
            start = time.perf_counter()
            with np.errstate(over="ignore", invalid="ignore"):  # a diverging run: its summary says so
                record = run_in_process(scheme, plan, subsystems, tap)
            wall_s = time.perf_counter() - start
        else:
            with ZenohBus(scene, plan, zenoh_options, listen, external, announce=announce, run_id=run_id,
                          routers=routers) as zbus:
                record, wall_s = zbus.drive(realtime, progress, status, tap, keep)
        if recorder is not None:
            recorder.finish("completed")
        return record, wall_s
    except BaseException as error:
        if started and recorder.result is None:
            try:
                recorder.finish(_outcome(error))
            except Exception as failure:  # the run's own error matters more
                error.add_note(f"the recording could not be finished: {failure}")
        raise
    finally:
        if recorder is not None:
            recorder.close()


def references(scene: Scene, keep: bool | None = None) -> tuple[dict, str | None]:
    """The references the scene asks for, or why there are none; ``keep`` as in ``execute`` (a long run's
    references are spilled to temporary files as they are computed)."""
    if scene.outputs.reference == "none":
        return {}, None
    if scene.outputs.reference == "extrapolated":
        return {}, ("no reference: 'extrapolated' is extrapolated by `zencosim study` from runs at several "
                    "macro-steps (docs/study.md); a single run has none")
    spill = spill_for(scene.manager.duration_ns // scene.manager.macro_step_ns, keep)
    if scene.outputs.reference == "solve_ivp":
        try:
            return {"solve_ivp": solve_ivp_reference(scene, spill=spill)}, None
        except ReferenceFailed as error:
            return {}, f"no reference: {error}"
    reason = monolithic_unavailable(scene)
    if reason:
        return {}, f"no analytic reference: {reason}"
    try:
        return {"analytic": analytic_reference(scene, spill), "monolithic": monolithic_reference(scene, spill)}, None
    except (ValueError, ArithmeticError) as error:  # e.g. masses 1e19 apart: the monolithic model is singular
        return {}, f"no analytic reference: {error}"


def summarize_run(scene: Scene, record: RunRecord, bus: str, wall_s: float, recorder: RunRecorder | None = None,
                  keep: bool | None = None) -> dict:
    """The summary of a run that ``execute`` returned (see ``manager.results.summary``), against the
    references the scene asks for (``keep`` as in ``execute``)."""
    with np.errstate(over="ignore", invalid="ignore"):  # the references and measures of a diverged run
        refs, note = references(scene, keep)
        return summarize(scene, record, bus, wall_s, refs, note, None if recorder is None else recorder.result)
