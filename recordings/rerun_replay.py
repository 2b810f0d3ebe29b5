"""Replay a recording in Rerun (``zencosim replay --rrd FILE`` / ``--spawn``): the view of
``recordings.rerun_view``, fed with every recorded message, the mechanism with every recorded command.

The recording's scene builds the mechanism and gives the spike detector's parameters; a recording
whose scene no longer loads is replayed without them (its signals are all there).
"""
from __future__ import annotations

from pathlib import Path

import rerun as rr

from zencosim.manager.wire.protocol import encode
from zencosim.recordings import RecordingError
from zencosim.recordings.reader import Recording
from zencosim.recordings.rerun_sinks import spawn_viewer
from zencosim.recordings.rerun_view import APPLICATION, PLOTTED, RunView, blueprint, ordered_commands


def replay_in_rerun(recording: Recording, rrd: str | Path | None = None, spawn: bool = False,
                    warn=lambda text: None) -> None:
    """Write ``recording`` to the Rerun file ``rrd`` and/or show it in a spawned viewer; ``warn`` hears what
    could not be shown. ViewerError (exit status 2) when ``spawn`` finds no viewer."""
    stream = rr.RecordingStream(APPLICATION, recording_id=recording.info["run_id"])
    sinks = [spawn_viewer(stream)] if spawn else []
    try:
        scene = recording.scene()
    except RecordingError as error:
        warn(f"{error}; replaying the signals without the mechanism and the spike detector")
        scene = None
    view = RunView(stream, [c.spec for c in recording.channels.values()], scene)
    for topic, channel in recording.channels.items():
        view.feed(topic, *channel.table(PLOTTED[channel.spec.role]))
    info = recording.info
    events, flagged = view.events(recording.end["outcome"] if recording.end else "ended (the recorder did not finish)",
                                  recording.last_step(), int(info["steps"]), int(info["macro_step_ns"]))
    view.commands(ordered_commands({c.spec.source: [encode(m.kind, m.step, m.time_ns, m.values, m.rows, m.ref)
                                                    for m in c.messages]
                                    for c in recording.channels.values() if c.spec.role == "inputs"}))
    view.last_frames()
    if rrd:
        sinks.append(rr.FileSink(str(rrd)))
    stream.set_sinks(*sinks, default_blueprint=blueprint(view, flagged[0] if flagged else None))
    stream.send_recording_name(f"{info['scene']} run {info['run_id']}")
    view.start()
    view.finish(events)
    stream.flush()
    stream.disconnect()
