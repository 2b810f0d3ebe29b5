"""Recording benchmark: what recording costs a run, and the message encoding it uses against JSON.

    python benchmarks/bench_recording.py [--repeats 5] [--zenoh-repeats 3] [--json out.json]

1. Overhead: macro-steps per second of two_mass_damped (10 000 steps of 1 ms) without and with
   ``--record``, on the in-process bus and over Zenoh, and over Zenoh without and with the live view
   (``--rerun connect=`` to a headless ``rerun --serve-grpc`` started here); each repeat runs both, in
   turn first, and the overhead is the median over repeats of the pairs' ratios (medians of the rates are
   shown too), with a 95 % confidence interval of that median (bootstrap) and the ratios' range; in process
   a third run of each repeat has the tap and no recorder process, which parts the tap's cost from what the
   recorder process's work on the other core costs the run. Also
   the time until the recording is complete (the recorder finishing after the last step) and the
   messages lost. On a shared machine these depend on what else runs; so, also, the cost on the
   stepping loop alone: CPU time per step of the in-process run plain, with the status, and with the
   status and the tap, whose batches go nowhere (no recorder process competing for a core) — the three
   side by side in one process, taking turns every 500 steps, so that the host's drift falls on all
   three alike (as separate runs in turn their pair ratios spread from −34 % to +60 %).
   In process, also a run without and a run with recording side by side in one process, taking turns
   every 500 steps, compared by the CPU time of each (``interleaved_overhead``), for the scene's 10 s and for
   ``LONG_S``: from the two, what recording costs per step and once per run (``per_step_and_fixed``).
2. Recorder ceiling: messages per second the recorder's writer takes (validate, encode and write
   MCAP, in batches as the tap sends them), alone on one core.
   Also the file's bytes per message, the time to read a recording back per message, and whether
   every float64 round-trips bit for bit. And the recorder process's pace: its work on the frames a 60 s
   in-process run hands over, per step, against the run's own step (``recorder_pace``): where it is the
   larger, it bounds a recorded run's wall time (the tap waits for the pipe; nothing is dropped).
"""
from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np
from rich.console import Console
from rich.table import Table

from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.bus.zenoh_session import free_tcp_port
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.wire.protocol import encode
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.layout import status_index
from zencosim.recordings.reader import read_recording
from zencosim.recordings.recorder import BATCH_MESSAGES, Recorder
from zencosim.recordings.recorder_process import channel_index, frame_messages
from zencosim.recordings.writer import RecordingWriter

SCENE = "two_mass_damped"
LONG_S = 100.0  # [s] of the scene's long runs side by side: recording's cost per step apart from its cost per run


def _in_turn(runs: list, repeat: int) -> list:
    """``runs`` in the order of repeat ``repeat``: each first in turn, so that a host whose speed drifts between
    repeats (here the hypervisor takes 0-40 % of the CPU) affects every kind of run alike."""
    first = repeat % len(runs)
    return runs[first:] + runs[:first]


BOOTSTRAP = 4000  # resamples for the confidence interval of a median of ratios


def _overhead_of(costs: list[float], baselines: list[float]) -> dict:
    """The median over repeats of each repeat's ratio ``cost / baseline``, minus one; the range of those; and a 95 %
    confidence interval of the median (percentile bootstrap over the repeats, seeded): on this host the ratios
    spread over tens of percent, and the interval says how far the median itself can be trusted."""
    ratios = np.array([cost / baseline for cost, baseline in zip(costs, baselines)])
    medians = np.median(np.random.default_rng(0).choice(ratios, size=(BOOTSTRAP, ratios.size)), axis=1)
    low, high = np.percentile(medians, [2.5, 97.5])
    return {"overhead": float(np.median(ratios)) - 1.0,
            "overhead_range": (float(ratios.min()) - 1.0, float(ratios.max()) - 1.0),
            "overhead_ci95": (float(low) - 1.0, float(high) - 1.0)}


def overhead(bus: str, repeats: int, workdir: Path, live: str | None = None) -> dict:
    """Steps/s without and with recording, time to a complete file, losses; with ``live`` (a ``--rerun`` target)
    the cost of the live view alone instead of the recording, and as losses the macro-steps not sent to it
    because it had fallen behind. Each repeat runs the kinds one after the other (``_in_turn``), and the overhead
    is the median over repeats of each pair's ratio. In process, a third kind runs with the tap and no recorder
    process (``_NullRecorder``): what the tap costs the run, apart from what the recorder process's work on the
    other core does to it (``tap_only``)."""
    scene = load_scene(SCENE)
    plain, recorded, tapped, complete, lost = [], [], [], [], []

    def run_plain(_repeat: int) -> None:
        record, wall = execute(scene, bus)
        plain.append(record.plan.n_ticks / wall)

    def run_recorded(repeat: int) -> None:
        recorder = Recorder(None, rerun=live) if live else Recorder(workdir / f"{bus}-{repeat}.mcap")
        started = time.perf_counter()
        record, wall = execute(scene, bus, recorder=recorder)
        complete.append(time.perf_counter() - started)
        recorded.append(record.plan.n_ticks / wall)
        lost.append(recorder.live_skipped[1] if live else recorder.result["lost"])

    def run_tapped(_repeat: int) -> None:
        record, wall = execute(scene, bus, recorder=_NullRecorder())
        tapped.append(record.plan.n_ticks / wall)

    kinds = [run_plain, run_recorded] + ([run_tapped] if bus == "inproc" and not live else [])
    for repeat in range(repeats):
        for run in _in_turn(kinds, repeat):
            run(repeat)
    return {"steps": plan_scene(scene)[0].n_ticks, "steps_per_s_without": statistics.median(plain),
            "steps_per_s_with": statistics.median(recorded),
            **_overhead_of(plain, recorded),  # of rates: without / with is the ratio of times with / without
            **({"tap_only": {"steps_per_s": statistics.median(tapped), **_overhead_of(plain, tapped)}}
               if tapped else {}),
            "recording_complete_s": statistics.median(complete),
            "lost": lost, "file_bytes": None if live else (workdir / f"{bus}-0.mcap").stat().st_size}


def interleaved_overhead(repeats: int, workdir: Path, duration: float | None = None) -> dict:
    """In process, a run without and a run with ``--record`` side by side in one process, taking turns every
    500 steps (``_side_by_side``): CPU µs per macro-step of each run's thread (the whole of ``execute``, so the
    recording's start and finish count against it), and the median over repeats of their ratio — a figure the
    host's drift, which falls on both alike, does not swing as it swings the runs in turn of ``overhead``.
    ``duration`` [s]: of the scene's runs (its own by default)."""
    scene = load_scene(SCENE, [] if duration is None else [f"manager.duration={duration}"])
    steps = plan_scene(scene)[0].n_ticks
    plain, recorded, lost = [], [], []
    for repeat in range(repeats):
        recorder = Recorder(workdir / f"turns-{repeat}.mcap")
        cpu = _side_by_side([lambda hand_over: execute(scene, "inproc", progress=hand_over),
                             lambda hand_over: execute(scene, "inproc", progress=hand_over, recorder=recorder)])
        plain.append(cpu[0] / steps * 1e6)
        recorded.append(cpu[1] / steps * 1e6)
        lost.append(recorder.result["lost"])
    return {"steps": steps, "cpu_us_without": statistics.median(plain), "cpu_us_with": statistics.median(recorded),
            **_overhead_of(recorded, plain), "lost": lost}


def per_step_and_fixed(short: dict, long: dict) -> dict:
    """What recording adds to a run's thread per step and once per run (starting and finishing the recorder), from
    the side-by-side figures of a short and a long run: the added CPU [µs] of each, against their steps."""
    added = [(f["cpu_us_with"] - f["cpu_us_without"]) * f["steps"] for f in (short, long)]
    per_step_us = (added[1] - added[0]) / (long["steps"] - short["steps"])
    return {"per_step_us": per_step_us, "per_step_overhead": per_step_us / long["cpu_us_without"],
            "fixed_ms": (added[0] - per_step_us * short["steps"]) * 1e-3}


def live_overhead(repeats: int, workdir: Path) -> dict:
    """The live view's cost over Zenoh: runs without and with ``--rerun connect=`` to a headless Rerun
    gRPC server started here (``rerun --serve-grpc``), alternating."""
    port = free_tcp_port()
    sink = subprocess.Popen([str(Path(sys.executable).with_name("rerun")), "--serve-grpc", "--port", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(2.0)  # the server listens
        return overhead("zenoh", repeats, workdir, live=f"connect=127.0.0.1:{port}")
    finally:
        sink.terminate()
        sink.wait()


class _NullRecorder(Recorder):
    """The tap with no recorder process: its batches are dropped. As a started recorder, it holds SIGINT and
    SIGTERM during a flush (in the main thread) until ``close``."""

    def __init__(self) -> None:
        super().__init__(os.devnull)

    def start(self, scene, plan, status: StatusReport, bus: str, run_id: str, realtime: bool) -> None:
        self._declare(plan, status, realtime)
        self._hold_signals()

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        pass

    def finish(self, outcome: str) -> dict:
        self.flush(last=True)
        self.finished = True
        self.result = {"outcome": outcome}
        return self.result


def stepping_loop(scene, what: str, plan, subsystems, progress: Callable[[int], None] | None = None) -> RunRecord:
    """One in-process run of ``scene``'s stepping loop (``plan_scene``: its plan and subsystems): ``plain``, with
    the ``status`` (logged by the scheme; without a tap nothing takes it), or with the status and the ``tap``
    (which encodes the statuses; its batches dropped); ``progress`` as ``make_scheme``'s. bench_instructions.py
    counts its instructions."""
    status = None if what == "plain" else StatusReport(plan, False)
    tap = _NullRecorder() if what == "tap" else None
    if tap is not None:
        tap.start(scene, plan, status, "inproc", "", False)
    try:
        # as a run makes it (manager.run.execute): the scheme calls the subsystems and hands the tap the messages
        scheme = make_scheme(scene, plan, status=status, progress=progress, direct=DirectCalls(plan, subsystems),
                             tap=tap)
        return run_in_process(scheme, plan, subsystems, tap)
    finally:
        if tap is not None:
            tap.close()


def _side_by_side(runs: list[Callable[[Callable[[int], None]], object]]) -> list[float]:
    """Run each of ``runs`` (called with a progress callback) in a thread of its own, one at a time, each handing
    over to the next at every progress callback; the CPU time [s] of each (``time.thread_time``). A run that
    raises ends its turns, and its error is raised here once every run has ended."""
    turns = threading.Condition()
    turn, running, cpu = [0], [True] * len(runs), [0.0] * len(runs)
    errors: list[BaseException] = []

    def pass_turn(i: int) -> None:  # with ``turns`` held: to the next run still going (itself if the only one)
        for k in range(1, len(runs) + 1):
            if running[(i + k) % len(runs)]:
                turn[0] = (i + k) % len(runs)
                break
        turns.notify_all()

    def body(i: int) -> None:
        def hand_over(_tick: int) -> None:
            with turns:
                pass_turn(i)
                turns.wait_for(lambda: turn[0] == i)

        with turns:
            turns.wait_for(lambda: turn[0] == i)
        started = time.thread_time()
        try:
            runs[i](hand_over)
        except BaseException as error:
            errors.append(error)
        finally:
            cpu[i] = time.thread_time() - started
            with turns:
                running[i] = False
                pass_turn(i)

    threads = [threading.Thread(target=body, args=(i,)) for i in range(len(runs))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
    return cpu


def stepping_loop_cost(repeats: int) -> dict:
    """CPU µs per macro-step of the in-process run (``stepping_loop``): plain, with the status, with status and
    tap, the three side by side in one process taking turns every ``PROGRESS_EVERY`` steps (``_side_by_side``), so
    that the host's drifting speed — it swings by half within minutes here — falls on the three alike; the
    overhead is the median over repeats of each repeat's ratio of status and tap to plain."""
    scene = load_scene(SCENE)
    kinds = ("plain", "status", "tap")
    found: dict[str, list[float]] = {what: [] for what in kinds}
    for _ in range(repeats):
        plans = {what: plan_scene(scene) for what in kinds}
        cpu = _side_by_side([functools.partial(stepping_loop, scene, what, *plans[what]) for what in kinds])
        for what, seconds in zip(kinds, cpu):
            found[what].append(seconds / plans[what][0].n_ticks * 1e6)
    return {"plain_us": statistics.median(found["plain"]), "status_us": statistics.median(found["status"]),
            "status_and_tap_us": statistics.median(found["tap"]), **_overhead_of(found["tap"], found["plain"])}


def wire_messages(path: Path) -> list[tuple[int, bytes]]:
    """The wire messages of a recording in recorded order per step, rebuilt from its stored messages
    (channel index, bytes)."""
    recording = read_recording(path)
    messages = []
    for index, channel in enumerate(recording.channels.values()):
        for m in channel.messages:
            messages.append((m.step, index, encode(m.kind, m.step, m.time_ns, m.values, rows=m.rows, ref=m.ref)))
    messages.sort(key=lambda item: item[0])
    return [(index, wire) for _, index, wire in messages]


def writer_ceiling(messages: list[tuple[int, bytes]], path: Path) -> dict:
    """Messages per CPU-second through the recorder's writer (validation, typed protobuf, MCAP, ZSTD) in
    batches of the tap's size, the file's bytes per message, and our decoder's time per message."""
    recording = read_recording(path)
    specs = [c.spec for c in recording.channels.values()]
    out = path.with_suffix(".ceiling.mcap")
    writer = RecordingWriter(out, recording.info, recording.scene_toml, specs)
    status = status_index(specs)
    started = time.process_time()
    for at in range(0, len(messages), BATCH_MESSAGES):
        batch = messages[at:at + BATCH_MESSAGES]
        channels = np.array([index for index, _ in batch], dtype=np.uint8)
        writer.write(channels, np.array([len(wire) for _, wire in batch]),
                     np.full(int(np.count_nonzero(channels == status)), time.time_ns()),
                     b"".join(wire for _, wire in batch))
    writer.finish("completed", None)
    per_s = len(messages) / (time.process_time() - started)
    started = time.process_time()
    decoded = read_recording(out)
    decode_us = (time.process_time() - started) / len(messages) * 1e6
    exact = all(a.values.tobytes() == b.values.tobytes() for topic, channel in recording.channels.items()
                for a, b in zip(channel.messages, decoded.channels[topic].messages))
    library_us = _library_decoded_us(out)
    return {"messages_per_s": per_s, "file_bytes_per_message": out.stat().st_size / len(messages),
            "read_us_per_message": decode_us, "exact_round_trip": exact,
            "mcap_library_decoded_us_per_message": library_us, "read_over_library": decode_us / library_us}


class _FramesKept(_NullRecorder):
    """The tap with no recorder process: its frames are kept (``frames``: kind and payload), and its channels."""

    def __init__(self) -> None:
        super().__init__()
        self.frames: list[tuple[int, bytes]] = []

    def _declare(self, plan, status: StatusReport, realtime: bool) -> list:
        self.specs = super()._declare(plan, status, realtime)
        return self.specs

    def _write_frame(self, kind: int, payload: bytes, steps: int | None = None) -> None:
        self.frames.append((kind, payload))


def recorder_pace(repeats: int, workdir: Path, duration: float = 60.0) -> dict:
    """What bounds a recorded in-process run's wall time: the recorder process's work (``recorder_process``: the
    messages built from the frames, encoded, compressed, written) on the frames a ``duration`` run hands over, CPU
    µs per step alone on one core (the least over ``repeats``), against the run's own CPU per step with the tap."""
    scene = load_scene(SCENE, [f"manager.duration={duration}"])
    tap = _FramesKept()
    started = time.thread_time()
    record, _ = execute(scene, "inproc", recorder=tap)
    steps = record.plan.n_ticks
    run_us = (time.thread_time() - started) / steps * 1e6
    status, index = status_index(tap.specs), channel_index(tap.specs)
    recorder_us = []
    for repeat in range(repeats):
        started = time.process_time()
        writer = RecordingWriter(workdir / f"pace-{repeat}.mcap", {"zencosim": "bench"}, "", tap.specs)
        for kind, data in tap.frames:
            writer.write(*frame_messages(kind, data, index, status))
        writer.finish("completed", None)
        recorder_us.append((time.process_time() - started) / steps * 1e6)
    return {"duration_s": duration, "steps": steps, "frames": len(tap.frames), "run_us_per_step": run_us,
            "recorder_us_per_step": min(recorder_us), "recorder_over_run": min(recorder_us) / run_us}


def _library_decoded_us(path: Path) -> float:
    """CPU µs per message of the mcap library's own decoded iteration of ``path`` (protobuf messages, with
    mcap-protobuf-support's decoder): issue 26's reference for reading a recording."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    started, count = time.process_time(), 0
    with open(path, "rb") as file:
        for _ in make_reader(file, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            count += 1
    return (time.process_time() - started) / count * 1e6


def _overhead(figures: dict) -> str:
    low, high = figures["overhead_range"]
    ci_low, ci_high = figures["overhead_ci95"]
    return (f"{figures['overhead'] * 100:.1f} % (95 % CI {ci_low * 100:.1f} … {ci_high * 100:.1f}; "
            f"range {low * 100:.1f} … {high * 100:.1f} %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="in-process runs of each kind")
    parser.add_argument("--loop-repeats", type=int, default=15, help="stepping-loop measurements of each kind")
    parser.add_argument("--zenoh-repeats", type=int, default=3, help="Zenoh runs of each kind")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="zencosim-bench-") as tmp:
        workdir = Path(tmp)
        figures = {"scene": SCENE, "cpus": os.cpu_count(), "load_average": os.getloadavg(),
                   "stepping_loop": stepping_loop_cost(args.loop_repeats),
                   "inproc": overhead("inproc", args.repeats, workdir),
                   "inproc_side_by_side": interleaved_overhead(args.repeats, workdir),
                   "inproc_side_by_side_long": interleaved_overhead(args.repeats, workdir, LONG_S),
                   "zenoh": overhead("zenoh", args.zenoh_repeats, workdir),
                   "live": live_overhead(args.zenoh_repeats, workdir)}
        messages = wire_messages(workdir / "inproc-0.mcap")
        figures["recorder"] = writer_ceiling(messages, workdir / "inproc-0.mcap")
        figures["recorder_pace"] = recorder_pace(args.repeats, workdir)

    table = Table(title=f"recording {SCENE}: medians ({args.repeats} in-process, {args.zenoh_repeats} Zenoh runs "
                        f"of each kind), load average {figures['load_average'][0]:.1f} on {figures['cpus']} cores")
    table.add_column("measure")
    table.add_column("value", justify="right")
    loop = figures["stepping_loop"]
    table.add_row("stepping loop: CPU per step plain / +status / +status+tap [µs] (medians)",
                  f"{loop['plain_us']:.1f} / {loop['status_us']:.1f} / {loop['status_and_tap_us']:.1f}")
    table.add_row("stepping loop: cost of recording on it (median of ratios; its 95 % CI; range)", _overhead(loop))
    live = figures["live"]
    table.add_row("zenoh: macro-steps/s without / with --rerun (live view)",
                  f"{live['steps_per_s_without']:.0f} / {live['steps_per_s_with']:.0f}")
    table.add_row("zenoh: overhead of the live view (target <= 5 %; median of ratios, CI, range)", _overhead(live))
    table.add_row("zenoh: macro-steps not sent to the live view (it fell behind), per run",
                  ", ".join(map(str, live["lost"])))
    for bus in ("inproc", "zenoh"):
        f = figures[bus]
        table.add_row(f"{bus}: macro-steps/s without / with --record",
                      f"{f['steps_per_s_without']:.0f} / {f['steps_per_s_with']:.0f}")
        table.add_row(f"{bus}: overhead of recording (target <= 10 %; median of ratios, CI, range)", _overhead(f))
        if "tap_only" in f:
            table.add_row(f"{bus}: macro-steps/s with the tap alone (no recorder process), in turn with the above",
                          f"{f['tap_only']['steps_per_s']:.0f}")
            table.add_row(f"{bus}: overhead of the tap alone (median of ratios, CI, range)", _overhead(f["tap_only"]))
        table.add_row(f"{bus}: run to complete recording [s]", f"{f['recording_complete_s']:.2f}")
        table.add_row(f"{bus}: messages lost per run", ", ".join(map(str, f["lost"])))
        table.add_row(f"{bus}: file size [bytes]", f"{f['file_bytes']}")
    turns = figures["inproc_side_by_side"]
    table.add_row("inproc, runs side by side in turns: CPU per step without / with --record [µs] (medians)",
                  f"{turns['cpu_us_without']:.1f} / {turns['cpu_us_with']:.1f}")
    table.add_row("inproc, runs side by side in turns: overhead of recording (target <= 10 %; median of ratios, "
                  "CI, range)", _overhead(turns))
    table.add_row("inproc, runs side by side in turns: messages lost per run", ", ".join(map(str, turns["lost"])))
    long = figures["inproc_side_by_side_long"]
    table.add_row(f"inproc, the same, {LONG_S:g} s runs: CPU per step without / with --record [µs]; overhead",
                  f"{long['cpu_us_without']:.2f} / {long['cpu_us_with']:.2f}; {_overhead(long)}")
    split = figures["inproc_recording_split"] = per_step_and_fixed(turns, long)
    table.add_row("inproc, recording per step (target <= 10 % of a step) and once per run (from the two lengths)",
                  f"{split['per_step_us']:.3f} µs = {split['per_step_overhead'] * 100:.1f} % of a step; "
                  f"{split['fixed_ms']:.2f} ms")
    recorder = figures["recorder"]
    table.add_row("recorder writer alone [messages/s of CPU]", f"{recorder['messages_per_s']:.0f}")
    pace = figures["recorder_pace"]
    table.add_row(f"recorder process's work on a {pace['duration_s']:g} s run's frames, alone [µs of CPU per step]; "
                  "over the run's step (what bounds a recorded run's wall time)",
                  f"{pace['recorder_us_per_step']:.2f}; {pace['recorder_over_run']:.1f}×")
    table.add_row("file [bytes/message]", f"{recorder['file_bytes_per_message']:.1f}")
    table.add_row("reading a recording [µs/message]", f"{recorder['read_us_per_message']:.2f}")
    table.add_row("the mcap library's decoded iteration [µs/message]",
                  f"{recorder['mcap_library_decoded_us_per_message']:.2f}")
    table.add_row("reading over the library's (issue 26: ≤ 1.2)", f"{recorder['read_over_library']:.2f}")
    table.add_row("every float64 round-trips exactly", str(recorder["exact_round_trip"]))
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
