"""Recording benchmark: what recording costs a run, and the message encoding it uses against JSON.

    python benchmarks/bench_recording.py [--repeats 5] [--zenoh-repeats 3] [--json out.json]

1. Overhead: macro-steps per second of two_mass_damped (10 000 steps of 1 ms) without and with
   ``--record``, on the in-process bus and over Zenoh; runs alternate, medians over repeats. Also
   the time until the recording is complete (the recorder finishing after the last step) and the
   messages lost. On a shared machine these depend on what else runs; so, also, the cost on the
   stepping loop alone: CPU time per step of the in-process run with the status and the tap, whose
   batches go nowhere (no recorder process competing for a core).
2. Recorder ceiling: messages per second the recorder's writer takes (encode and write MCAP), alone
   on one core.
3. Encoding: the real messages of a recorded run, encoded as our protobuf and as JSON with a JSON
   schema (NaN and infinities as strings): bytes per message raw and in a ZSTD-chunked MCAP, encode
   and decode time, and whether every float64 round-trips bit for bit.
"""
from __future__ import annotations

import argparse
import io
import json
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer
from rich.console import Console
from rich.table import Table

from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.replica import Replica
from zencosim.manager.wire.protocol import HEADER, encode
from zencosim.manager.wire.status import StatusReport
from zencosim.recordings.layout import channel_specs
from zencosim.recordings.reader import read_recording
from zencosim.recordings.recorder import Recorder
from zencosim.recordings.schema import decode_stored, encode_wire
from zencosim.recordings.writer import CHUNK_BYTES, RecordingWriter

SCENE = "two_mass_damped"


def overhead(bus: str, repeats: int, workdir: Path) -> dict:
    """Steps/s without and with recording (alternating), time to a complete file, losses."""
    scene = load_scene(SCENE)
    plain, recorded, complete, lost = [], [], [], []
    for i in range(repeats):
        record, wall = execute(scene, bus)
        plain.append(record.plan.n_ticks / wall)
        recorder = Recorder(workdir / f"{bus}-{i}.mcap")
        started = time.perf_counter()
        record, wall = execute(scene, bus, recorder=recorder)
        complete.append(time.perf_counter() - started)
        recorded.append(record.plan.n_ticks / wall)
        lost.append(recorder.result["lost"])
    without, with_ = statistics.median(plain), statistics.median(recorded)
    return {"steps": record.plan.n_ticks, "steps_per_s_without": without, "steps_per_s_with": with_,
            "overhead": without / with_ - 1.0, "recording_complete_s": statistics.median(complete),
            "lost": lost, "file_bytes": (workdir / f"{bus}-0.mcap").stat().st_size}


class _NullRecorder(Recorder):
    """The in-process tap with no recorder process: its batches are dropped."""

    def __init__(self, plan, status: StatusReport) -> None:
        super().__init__(os.devnull)
        self._declare(channel_specs(plan, status), realtime=False)

    def _write_frame(self, kind: int, payload: bytes) -> None:
        pass


def stepping_loop_cost(repeats: int) -> dict:
    """CPU µs per macro-step of the in-process run: plain, with the status, with status and tap."""
    scene = load_scene(SCENE)
    plan, _ = plan_scene(scene)
    names = [s.name for s in plan.subsystems]

    def cpu_per_step(status: StatusReport | None, tap) -> float:
        replica = Replica(make_scheme(scene, plan, status=status), names, endpoints(plan, plan_scene(scene)[1]), tap=tap)
        started = time.process_time()
        replica.run()
        return (time.process_time() - started) / plan.n_ticks * 1e6

    plain, with_status, with_tap = [], [], []
    for _ in range(repeats):
        plain.append(cpu_per_step(None, None))
        with_status.append(cpu_per_step(StatusReport(plan, False), None))
        status = StatusReport(plan, False)
        with_tap.append(cpu_per_step(status, _NullRecorder(plan, status).tap))
    return {"plain_us": min(plain), "status_us": min(with_status), "status_and_tap_us": min(with_tap),
            "overhead": min(with_tap) / min(plain) - 1.0}


def wire_messages(path: Path) -> list[tuple[int, bytes]]:
    """The wire messages of a recording, rebuilt from its stored messages (channel index, bytes)."""
    recording = read_recording(path)
    messages = []
    for index, channel in enumerate(recording.channels.values()):
        for m in channel.messages:
            messages.append((index, encode(m.kind, m.step, m.time_ns, m.values, rows=m.rows, ref=m.ref)))
    return messages


def writer_ceiling(messages: list[tuple[int, bytes]], path: Path) -> float:
    """Messages per second through the recorder's writer (validation, encoding, MCAP, compression)."""
    recording = read_recording(path)
    writer = RecordingWriter(path.with_suffix(".ceiling.mcap"), recording.info, recording.scene_toml,
                             [c.spec for c in recording.channels.values()])
    started = time.process_time()
    for index, wire in messages:
        writer.write(index, wire, 0)
    writer.finish("completed", None)
    return len(messages) / (time.process_time() - started)


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else ("NaN" if math.isnan(x) else ("Infinity" if x > 0 else "-Infinity"))


def _from_json_float(x: float | str) -> float:
    return float(x) if isinstance(x, (int, float)) else float({"NaN": "nan", "Infinity": "inf", "-Infinity": "-inf"}[x])


def encode_json(wire: bytes) -> bytes:
    _version, kind, rows, count, step, time_ns, ref = HEADER.unpack_from(wire)
    values = np.frombuffer(wire, "<f8", count, HEADER.size).tolist()
    return json.dumps({"step": step, "time_ns": time_ns, "kind": kind, "rows": rows, "ref": ref,
                       "values": [_json_float(v) for v in values]}, separators=(",", ":")).encode()


def decode_json(data: bytes) -> np.ndarray:
    return np.array([_from_json_float(v) for v in json.loads(data)["values"]], dtype=np.float64)


def _mcap_bytes(encoded: list[tuple[int, bytes]], encoding: str) -> int:
    stream = io.BytesIO()
    writer = Writer(stream, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
    writer.start()
    schema = writer.register_schema("m", encoding, b"")
    channels = [writer.register_channel(f"c{i}", encoding, schema) for i in range(8)]
    for t, (index, data) in enumerate(encoded):
        writer.add_message(channels[index], t, data, t)
    writer.finish()
    return len(stream.getvalue())


def encodings(messages: list[tuple[int, bytes]]) -> dict:
    """Size and speed of protobuf (ours) and JSON on the same messages; exact round trip of each."""
    wires = [w for _, w in messages if HEADER.unpack_from(w)[1] != 18]  # values only (no ERROR text)
    payloads = [np.frombuffer(w, "<f8", offset=HEADER.size) for w in wires]
    figures = {}
    for name, encoder, decoder, mcap_encoding in (
            ("protobuf", lambda w: encode_wire(w, "bench")[1], lambda d: decode_stored(d).values, "protobuf"),
            ("json", encode_json, decode_json, "json")):
        started = time.process_time()
        encoded = [encoder(w) for w in wires]
        encode_us = (time.process_time() - started) / len(wires) * 1e6
        started = time.process_time()
        decoded = [decoder(d) for d in encoded]
        decode_us = (time.process_time() - started) / len(wires) * 1e6
        exact = all(a.tobytes() == b.tobytes() for a, b in zip(payloads, decoded))
        figures[name] = {"bytes_per_message": sum(map(len, encoded)) / len(encoded),
                         "mcap_zstd_bytes_per_message": _mcap_bytes(list(zip((i for i, _ in messages), encoded)),
                                                                    mcap_encoding) / len(encoded),
                         "encode_us": encode_us, "decode_us": decode_us, "exact_round_trip": exact}
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="in-process runs of each kind")
    parser.add_argument("--zenoh-repeats", type=int, default=3, help="Zenoh runs of each kind")
    parser.add_argument("--json", help="write the figures as JSON")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="zencosim-bench-") as tmp:
        workdir = Path(tmp)
        figures = {"scene": SCENE, "cpus": os.cpu_count(), "load_average": os.getloadavg(),
                   "stepping_loop": stepping_loop_cost(args.repeats),
                   "inproc": overhead("inproc", args.repeats, workdir),
                   "zenoh": overhead("zenoh", args.zenoh_repeats, workdir)}
        messages = wire_messages(workdir / "inproc-0.mcap")
        figures["recorder_messages_per_s"] = writer_ceiling(messages, workdir / "inproc-0.mcap")
        figures["encodings"] = encodings(messages)

    table = Table(title=f"recording {SCENE}: medians ({args.repeats} in-process, {args.zenoh_repeats} Zenoh runs "
                        f"of each kind), load average {figures['load_average'][0]:.1f} on {figures['cpus']} cores")
    table.add_column("measure")
    table.add_column("value", justify="right")
    loop = figures["stepping_loop"]
    table.add_row("stepping loop: CPU per step plain / +status / +status+tap [µs]",
                  f"{loop['plain_us']:.1f} / {loop['status_us']:.1f} / {loop['status_and_tap_us']:.1f}")
    table.add_row("stepping loop: cost of recording on it (min over repeats)", f"{loop['overhead'] * 100:.1f} %")
    for bus in ("inproc", "zenoh"):
        f = figures[bus]
        table.add_row(f"{bus}: macro-steps/s without / with --record",
                      f"{f['steps_per_s_without']:.0f} / {f['steps_per_s_with']:.0f}")
        table.add_row(f"{bus}: overhead of recording (target <= 10 %)", f"{f['overhead'] * 100:.1f} %")
        table.add_row(f"{bus}: run to complete recording [s]", f"{f['recording_complete_s']:.2f}")
        table.add_row(f"{bus}: messages lost per run", ", ".join(map(str, f["lost"])))
        table.add_row(f"{bus}: file size [bytes]", f"{f['file_bytes']}")
    table.add_row("recorder writer alone [messages/s of CPU]", f"{figures['recorder_messages_per_s']:.0f}")
    for name, f in figures["encodings"].items():
        table.add_row(f"{name}: bytes/message raw / in ZSTD MCAP",
                      f"{f['bytes_per_message']:.1f} / {f['mcap_zstd_bytes_per_message']:.1f}")
        table.add_row(f"{name}: encode / decode [µs/message]", f"{f['encode_us']:.2f} / {f['decode_us']:.2f}")
        table.add_row(f"{name}: every float64 round-trips exactly", str(f["exact_round_trip"]))
    Console().print(table)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
