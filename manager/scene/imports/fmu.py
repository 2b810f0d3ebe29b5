"""One FMU alone as a scene: ``zencosim run model.fmu``, as ``fmpy simulate`` or ``fmpy.simulate_fmu`` runs it.

The scene has one subsystem, the FMU (named after its model identifier), with no coupling; it publishes
every output variable (``outputs = "all"``) and runs its default experiment as fmpy reads it: the
duration ``stopTime − startTime`` (else 1 s), the step ``stepSize`` (else the Co-Simulation
``fixedInternalStepSize``, else fmpy's ``auto_interval`` of the duration), one ``doStep`` of that size per
macro-step (Model Exchange: zencosim's integrator at that step). Options, as a system description's
overrides take them (``manager.scene.load``): ``input`` a CSV table of input values over time
(``subsystems.models.external.table``), ``start.<variable>`` start values (SI). A start time other than 0
is refused: zencosim starts its FMUs at t = 0.
"""
from __future__ import annotations

from pathlib import Path

from zencosim.manager.scene.imports import (
    Component,
    document_path,
    read_fmu,
    refusal,
    scene_name,
    number,
    settle_duration,
    step_ns,
)
from zencosim.manager.scene.load import SceneError
from zencosim.subsystems.params import Problems

DEFAULT_STOP = 1.0  # [s] fmpy's duration when the FMU gives no stopTime


def import_fmu(path: Path, duration: float | None = None, input_table: str | None = None) -> tuple[dict, list[str]]:
    """The scene document of the FMU at ``path`` run alone and the notes on it; ``input_table``: the path of
    a CSV file of input values (relative to the current directory)."""
    fmu, why = read_fmu(path, path.name)
    if fmu is None:
        raise refusal(path, "fmu", why)
    from fmpy.util import auto_interval
    model = fmu.description
    experiment = model.defaultExperiment
    notes: list[str] = []
    problems = Problems()
    start = _experiment_time(experiment, "startTime", problems) or 0.0
    if start != 0.0:
        problems.add("DefaultExperiment.startTime", f"{start!r} s: zencosim starts its FMUs at t = 0")
    stop = _experiment_time(experiment, "stopTime", problems)
    declared = None if stop is None else stop - start
    fixed = model.coSimulation.fixedInternalStepSize if model.coSimulation is not None else None
    if experiment is not None and experiment.stepSize is not None:
        step, origin = _experiment_time(experiment, "stepSize", problems), "the DefaultExperiment's stepSize"
    elif fixed is not None:
        step = number(str(fixed), "CoSimulation.fixedInternalStepSize", "fixedInternalStepSize [s]", problems)
        origin = "the Co-Simulation fixedInternalStepSize"
    else:
        step = float(auto_interval(duration or declared or DEFAULT_STOP))
        origin = "fmpy's auto_interval of the duration (the FMU gives no step)"
    if step is not None:
        step_ns(step, "DefaultExperiment.stepSize", f"the step ({origin})", problems)
    if problems:
        raise SceneError(str(path), problems)
    notes.append(f"manager.macro_step = {step!r} s: {origin}")
    name = scene_name(model.coSimulation.modelIdentifier if model.coSimulation is not None else fmu.model_name,
                      set(), "the FMU's model identifier", notes)
    component = Component(name, "fmu", fmu, document_path(path, path.parent), step)
    run_for = settle_duration(duration, declared, "the DefaultExperiment's stopTime - startTime" if declared
                              else f"fmpy's {DEFAULT_STOP} s", step, [component], problems, notes)
    if problems:
        raise SceneError(str(path), problems)
    table: dict = {"model": "fmu", "fmu": component.path, "micro_step": step, "outputs": "all"}
    if input_table is not None:
        table["input_table"] = Path(input_table).resolve().as_posix()
    return {"name": name, "description": f"the FMU {path.name} run alone",
            "manager": {"duration": run_for, "macro_step": step},
            "outputs": {"reference": "none"},
            "subsystems": {name: table}}, notes


def _experiment_time(experiment, name: str, problems: Problems) -> float | None:
    """A DefaultExperiment attribute [s] as a finite float; None when absent, or with a problem."""
    text = getattr(experiment, name, None) if experiment is not None else None
    return None if text is None else number(text, f"DefaultExperiment.{name}", f"{name} [s]", problems)
