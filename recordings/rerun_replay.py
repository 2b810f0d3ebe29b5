"""Replay a recording in Rerun: one scalar time series per recorded signal, logged column by column.

Timelines: ``step`` (the communication point) and ``sim_time`` (simulated time, integer ns). Entity
paths: ``/<subsystem>/<output>`` for every output a subsystem reported, ``/<subsystem>/<input>`` for
every input it received with a STEP command (the value of the input polynomial at the start of the
step, i.e. its constant coefficient; the INIT command's inputs at t0 are not repeated), ``/manager/<field>/<bond>`` for the manager's per-bond status
(``delta_p``, ``delta_e``, and the correction terms when a run has them) and ``/manager/timing/<field>``
for the wall-clock measurements. Each entity is one ``send_columns`` call. The blueprint has one
time-series panel per subsystem, one for residual power and energy, one for timing.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.layout import STATUS_TOPIC
from zencosim.recordings.reader import ChannelRecord, Recording

APPLICATION = "zencosim"
TIMING = "timing"


def _path(*parts: str) -> str:
    return "/" + "/".join(rr.escape_entity_path_part(part) for part in parts)


def status_entity(name: str, measured: bool) -> str:
    """Entity path of a status field: ``delta_p.c`` → ``/manager/delta_p/c``; measured → ``/manager/timing/<name>``."""
    return _path("manager", TIMING, name) if measured else _path("manager", *name.split(".", 1))


def signal_series(recording: Recording) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Entity path → (steps, simulated times [ns], values) of every series the replay logs."""
    series = {}
    for topic, channel in recording.channels.items():
        spec = channel.spec
        if topic == STATUS_TOPIC:
            steps, times, values = channel.table(Kind.STATUS)
            for j, name in enumerate(spec.names):
                series[status_entity(name, name in spec.measured)] = (steps, times, values[:, j])
        elif spec.role == "outputs":
            steps, times, values = channel.table(Kind.OUTPUT)
            for j, name in enumerate(spec.names):
                series[_path(spec.source, name)] = (steps, times, values[:, j])
        else:
            steps, times, values = _inputs(channel)
            for j, name in enumerate(spec.names):
                series[_path(spec.source, name)] = (steps, times, values[:, j])
    return series


def _inputs(channel: ChannelRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constant coefficient (first row) of every STEP command."""
    commands = [m for m in channel.messages if m.kind == Kind.STEP]
    n = len(channel.spec.names)
    values = np.array([m.values[:n] for m in commands]).reshape(len(commands), n)
    return (np.array([m.step for m in commands], dtype=np.int64), np.array([m.time_ns for m in commands], dtype=np.int64),
            values)


def blueprint(recording: Recording) -> rrb.Blueprint:
    sources = list(dict.fromkeys(c.spec.source for c in recording.channels.values() if c.spec.source != "manager"))
    status = recording.channels[STATUS_TOPIC].spec
    bond_fields = sorted({name.split(".", 1)[0] for name in status.names if name not in status.measured})
    return rrb.Blueprint(rrb.Vertical(
        rrb.Horizontal(*(rrb.TimeSeriesView(origin=_path(source), name=f"subsystem {source}") for source in sources)),
        rrb.Horizontal(
            rrb.TimeSeriesView(origin="/manager", contents=[f"{_path('manager', f)}/**" for f in bond_fields],
                               name="residual power and energy"),
            rrb.TimeSeriesView(origin=_path("manager", TIMING), name="timing [s]"))),
        collapse_panels=True)


def replay_in_rerun(recording: Recording, rrd: str | Path | None = None, spawn: bool = False) -> None:
    """Write ``recording`` to the Rerun file ``rrd`` and/or show it in a spawned viewer."""
    stream = rr.RecordingStream(APPLICATION, recording_id=recording.info["run_id"])
    sinks = ([rr.FileSink(str(rrd))] if rrd else []) + ([rr.GrpcSink()] if spawn else [])
    if spawn:
        rr.spawn(connect=False)
    stream.set_sinks(*sinks, default_blueprint=blueprint(recording))
    stream.send_recording_name(f"{recording.info['scene']} run {recording.info['run_id']}")
    for entity, (steps, times, values) in signal_series(recording).items():
        stream.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=steps),
                                             rr.TimeColumn("sim_time", duration=times.astype("timedelta64[ns]"))],
                            columns=rr.Scalars.columns(scalars=values))
    stream.flush()
    stream.disconnect()
