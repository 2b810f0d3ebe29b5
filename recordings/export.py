"""The signals of a recording, as a run gives them (``manager.results.tables``): ``zencosim export``.

A recording holds every reply of every subsystem and the manager's status after every macro-step.
The committed output of a subsystem at a communication point is the last OUTPUT it sent for that
point (the implicit scheme's predictor and derivative runs come before its corrector); rows run up to
the last macro-step whose status was recorded, which is the last step the run committed. The residual
power and energy of a bond are the status's ``delta_p.<bond>`` and ``delta_e.<bond>`` (0 at the start,
as in the run). The grid of each signal comes from the recording's own scene (an energy-controlled run's: t_0
and the step of every status), so the tables equal those of the run that was recorded, bit for bit.
"""
from __future__ import annotations

import numpy as np

from zencosim.manager.assembly import plan_scene
from zencosim.manager.results.tables import Signal, run_signals
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings import RecordingError
from zencosim.recordings.layout import STATUS_TOPIC
from zencosim.recordings.reader import Recording


def recorded_signals(recording: Recording) -> dict[str, Signal]:
    """Every signal of the recorded run (see the module text); RecordingError when its scene cannot be loaded."""
    scene = recording.scene()
    plan, _ = plan_scene(scene)
    needed = [f"{sub.name}/y" for sub in plan.subsystems] + [STATUS_TOPIC]
    missing = [topic for topic in needed if topic not in recording.channels]
    if missing:
        raise RecordingError(f"{recording.path}: channels {', '.join(missing)} are missing; its scene has "
                             f"{', '.join(needed)}")
    last_step = recording.last_step()
    status = recording.channels[STATUS_TOPIC]
    point_ticks = None
    if scene.manager.step_control == "energy":  # a row per point: t_0 and every status's step
        point_ticks = np.array([0, *(message.step for message in status.messages)], dtype=np.int64)
        rows = {int(tick): row for row, tick in enumerate(point_ticks)}
    trajectories = []
    for sub in plan.subsystems:
        names = recording.channels[f"{sub.name}/y"].spec.names
        if list(names) != [port.name for port in sub.outputs]:  # another subsystem's replies, or another model's
            raise RecordingError(f"{recording.path}: channel {sub.name}/y holds {', '.join(names)}; its scene's "
                                 f"{sub.name} has {', '.join(p.name for p in sub.outputs)}{recording.damage_note()}")
        count = (plan.n_ticks if point_ticks is None else len(point_ticks) - 1) // sub.ratio + 1
        outputs = np.full((count, len(sub.outputs)), np.nan)
        for message in recording.channels[f"{sub.name}/y"].messages:
            if message.kind == Kind.OUTPUT and message.step <= last_step:
                point = message.step if point_ticks is None else rows.get(message.step)
                if point is not None and point % sub.ratio == 0:
                    outputs[point // sub.ratio] = message.values
        trajectories.append(outputs)
    count = plan.n_ticks + 1 if point_ticks is None else len(point_ticks)
    residual = {prefix: np.full((count, len(plan.bonds)), np.nan) for prefix in ("delta_p", "delta_e")}
    for prefix, values in residual.items():
        values[0] = 0.0
    columns = {name: i for i, name in enumerate(status.spec.names)}
    for number, message in enumerate(status.messages, start=1):
        row = message.step if point_ticks is None else number
        for prefix, values in residual.items():
            values[row] = [message.values[columns[f"{prefix}.{bond.name}"]] for bond in plan.bonds]
    return run_signals(plan, trajectories, residual["delta_p"], residual["delta_e"], last_step, point_ticks)
