"""The live view of a run: a process fed the recorder's frames, streaming the run to Rerun as it goes.

    python -m zencosim.recordings.rerun_live     (started by recordings.recorder.Recorder, never by hand)

Its standard input carries the frames of ``recordings.recorder_process`` (START with ``target``:
``spawn``, ``connect=ADDR`` or ``serve``; BATCH and STEPS frames; END). The tap that feeds it is the recorder's
(the in-process replica, or the manager's replica following a Zenoh run), so the view costs the
stepping loop nothing more than a recording does: the decoding and logging run here, on the other
core. Each channel's messages go to ``recordings.rerun_view.RunView`` in order, as the replay feeds
a recording's, so the live view and the replay of the run's recording log the same values; the
mechanism is re-executed from the commands and drawn every ``LIVE_FRAME_NS`` of simulated time (the
replay draws every step: the live view's frames are some of the replay's). What arrives is sent at most ``FRAME_RATE`` times a
second (the viewer's frame rate): a batch of many steps goes as one ``send_columns`` per series.

The manager does not wait for this view: a batch for which its pipe has no room is not sent
(``recordings.recorder``), and the view says the gap on its timeline and stops the mechanism there.

``serve`` keeps the gRPC server and the web viewer up after the run, until the process is ended
(the command line waits for Ctrl-C). Standard output gets one JSON line when ready (with the web
viewer's address for ``serve``) and one when finished.
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np
import rerun as rr

from zencosim.manager.scene.load import SceneError, scene_from_text
from zencosim.manager.wire.protocol import HEADER
from zencosim.recordings import RecordingError
from zencosim.recordings.encoding import wire_headers
from zencosim.recordings.layout import SCENE_ATTACHMENT, ChannelSpec, status_index
from zencosim.recordings.mechanism import LIVE_FRAME_NS
from zencosim.recordings.recorder_process import (
    CONTROL,
    NO_END,
    FrameReader,
    announce,
    channel_index,
    frame_messages,
    observe,
)
from zencosim.recordings.rerun_sinks import serve_web, spawn_viewer, viewer_url
from zencosim.recordings.rerun_view import APPLICATION, PLOTTED, RunView, blueprint

FRAME_RATE = 30.0  # [1/s] sends to the viewer at most this often


def open_stream(target: str, run_id: str) -> tuple[rr.RecordingStream, list, str]:
    """The stream of the run, its sink and what to tell the user."""
    stream = rr.RecordingStream(APPLICATION, recording_id=run_id)
    if target == "spawn":
        return stream, [spawn_viewer(stream)], "a Rerun viewer"
    if target.startswith("connect="):
        url = viewer_url(target.removeprefix("connect="))
        return stream, [rr.GrpcSink(url)], url
    if target == "serve":
        return stream, [], serve_web(stream)
    raise RecordingError(f"--rerun {target}: expected spawn, connect=HOST:PORT or serve")


def main() -> int:
    frames, start = observe()
    if start is None:
        return 2
    info = start["metadata"]
    specs = [ChannelSpec.from_metadata(c["topic"], c["metadata"]) for c in start["channels"]]
    try:
        scene = scene_from_text(start["scene_toml"], SCENE_ATTACHMENT)
        stream, sinks, where = open_stream(start["target"], info["run_id"])
    except (RecordingError, SceneError) as error:
        announce({"event": "error", "reason": str(error)})
        return 2
    view = RunView(stream, specs, scene, LIVE_FRAME_NS)
    if sinks:
        stream.set_sinks(*sinks, default_blueprint=blueprint(view))
    else:
        stream.send_blueprint(blueprint(view))
    stream.send_recording_name(f"{info['scene']} run {info['run_id']} (live)")
    view.start()
    announce({"event": "ready", "where": where})
    outcome, last_step = follow(frames, view, specs, int(info["macro_step_ns"]))
    events, flagged = view.events(outcome, last_step, int(info["steps"]), int(info["macro_step_ns"]))
    view.last_frames()
    view.finish(events)
    stream.send_blueprint(blueprint(view, flagged[0] if flagged else None))
    stream.flush()
    announce({"event": "finished", "where": where})
    if start["target"] == "serve":
        while frames.stop.received is None:  # serving until ended
            time.sleep(0.2)
    stream.disconnect()
    return 0


def follow(frames: FrameReader, view: RunView, specs: list[ChannelSpec], macro_step_ns: int) -> tuple[str, int]:
    """Feed the view every batch until END; return the run's outcome and its last reported step. A batch
    is read with numpy (``recordings.encoding.wire_headers``): each channel's plotted messages become
    arrays at once; only the commands of drawn subsystems are taken one by one, for the mechanism. A
    batch holds whole steps (a step's replies, its status, the next commands): one whose first status is not
    the step after the last one seen follows batches the manager skipped (this view fell behind,
    ``recordings.recorder``), which the view says on its timeline."""
    status, channel_of = status_index(specs), channel_index(specs)
    last_step, sent = 0, time.monotonic()
    while (frame := frames.next()) is not None:
        kind, data, _ = frame
        if kind == CONTROL:
            return json.loads(data)["outcome"], last_step
        channels, sizes, _, messages = frame_messages(kind, data, channel_of, status)
        raw = np.frombuffer(messages, dtype=np.uint8)
        starts, heads, valid = wire_headers(sizes, raw)
        statuses = np.flatnonzero(valid & (channels == status))
        if statuses.size and int(heads["step"][statuses[0]]) > last_step + 1:
            view.gap(last_step, int(heads["step"][statuses[0]]), macro_step_ns)
        for index, spec in enumerate(specs):
            width = len(spec.names)
            chosen = np.flatnonzero(valid & (channels == index) & (heads["kind"] == PLOTTED[spec.role])
                                    & (heads["count"] >= width))
            values = raw[starts[chosen, None] + HEADER.size + np.arange(8 * width)].view("<f8").reshape(-1, width)
            view.feed(spec.topic, heads["step"][chosen], heads["time_ns"][chosen], values)
            if spec.role == "status" and chosen.size:
                last_step = int(heads["step"][chosen[-1]])
        drawn = view.mechanism.drawn if view.mechanism is not None else ()  # none after a gap (RunView.gap)
        commands = [(specs[i].source, messages[starts[k]:starts[k] + sizes[k]])
                    for k, i in enumerate(channels.tolist()) if specs[i].source in drawn and specs[i].role == "inputs"
                    and valid[k]]
        view.commands(commands)
        if time.monotonic() - sent >= 1.0 / FRAME_RATE:
            view.flush()
            sent = time.monotonic()
    return ("stopped by SIGTERM: " if frames.stop.received else "") + NO_END, last_step


if __name__ == "__main__":
    sys.exit(main())
