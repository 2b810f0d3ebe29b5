"""``zencosim replay``, ``inspect`` and ``export``: what a recording holds, its signals, a Rerun view of it, and
its verification by re-running its scene."""
from __future__ import annotations

import argparse

from rich.markup import escape
from rich.table import Table

from zencosim.cli.console import examples, out, say, warn
from zencosim.extras import require
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.results.tables import check_table_path, tables, write_tables
from zencosim.recordings import RecordingError
from zencosim.recordings.reader import read_recording


def cmd_replay(args: argparse.Namespace) -> int:
    if not (args.rrd or args.spawn or args.verify):
        raise RecordingError(f"replay {args.recording}: nothing to do; give --rrd FILE, --spawn or --verify")
    rrd = check_output_file(args.rrd, "Rerun recording", (".rrd",)) if args.rrd else None
    if rrd or args.spawn:
        require("rerun", "replaying in Rerun")
    recording = read_recording(args.recording)
    if recording.truncated:
        warn(f"{recording.path}: {recording.truncated}; replaying what it holds")
    if recording.damage and (rrd or args.spawn):
        warn(f"{recording.path} is damaged: {'; '.join(recording.damage)}; replaying what it holds")
    status = 0
    if rrd or args.spawn:
        from zencosim.recordings.rerun_replay import replay_in_rerun
        replay_in_rerun(recording, rrd, args.spawn, warn)
        if rrd:
            say(f"wrote {rrd}")
    if args.verify:
        from zencosim.manager.bus.watchdog import model_watch
        from zencosim.recordings.verify import verify
        # said by a watched command's parent should the re-run, having compared every message, end the process
        result = verify(recording, lambda so_far: model_watch().say_if_ended(_verdict(so_far, recording)[0]))
        for line in _verdict(result, recording):
            say(line)
        status = 0 if result.passed else 1
    return status


def _verdict(result, recording) -> list[str]:
    """What ``replay --verify`` says of ``result`` (``recordings.verify.Verification``) on ``recording``."""
    compared = sum(result.compared.values())
    held = (f"first divergence at {result.divergence}" if result.divergence is not None
            else "it holds no messages to verify" if result.empty
            else f"the {compared} messages it holds up to step {result.last_step} are bit-identical to a re-run")
    if result.damage:
        lines = [f"verify FAILED: the file is damaged: {'; '.join(result.damage)}"
                 + (f"; {result.truncated}" if result.truncated else "") + f"; {held}"]
    elif result.truncated:
        lines = [f"verify INCOMPLETE: {result.truncated}; missing: what followed"
                 + (", the end record among it" if recording.end is None else "") + f"; {held}"]
    elif result.divergence is not None:
        lines = [f"verify FAILED: first divergence at {result.divergence}"]
    elif result.empty:
        lines = [f"verify FAILED: {recording.path} holds no messages to verify"]
    elif result.failure is not None and not result.passed:
        lines = [f"verify FAILED: the re-run failed before the recording's end ({result.failure}); the {compared} "
                 f"messages before it are bit-identical; " + (result.note or f"the recorded run: {result.outcome}")]
    elif not result.passed:
        lines = [f"verify FAILED: {result.note}"]
    else:
        lines = [f"verify passed: {compared} messages bit-identical to a re-run, up to step {result.last_step}"
                 + (f" ({result.note})" if result.note else "")]
    if result.failure is not None and result.passed:
        lines.append(f"the re-run then failed as the run did: {result.failure}" if result.reproduced
                     else f"the re-run then failed: {result.failure} (the recorded run: {result.outcome or 'unknown'})")
    return lines


def cmd_inspect(args: argparse.Namespace) -> int:
    from zencosim.recordings.reader import describe
    info = describe(read_recording(args.recording))
    host = f"host {info['host']}, " if info["host"] else ""
    table = Table(title=escape(f"{info['file']}: scene {info['scene']}, run {info['run_id']} ({info['bus']} bus, "
                               f"{host}zencosim {info['zencosim']})"))
    table.add_column("channel")
    table.add_column("messages", justify="right")
    table.add_column("values")
    for topic, channel in info["channels"].items():
        table.add_row(escape(topic), str(channel["messages"]), escape(channel["values"]))
    out.print(table)
    say(f"started {info['started']}; steps {info['steps']}, {info['duration_s']:g} s simulated; "
        f"outcome: {info['outcome']}; lost: {'unknown' if info['lost'] is None else info['lost']}")
    if info["truncated"]:
        say(f"incomplete: {info['truncated']}")
    for damage in info["damage"]:
        say(f"damaged: {damage}")
    return 0 if info["complete"] and not info["damage"] else 1


def cmd_export(args: argparse.Namespace) -> int:
    from zencosim.recordings.export import recorded_signals
    out_path = check_table_path(args.out)
    recording = read_recording(args.recording)
    if recording.truncated:
        warn(f"{recording.path}: {recording.truncated}; exporting what it holds")
    if recording.damage:
        warn(f"{recording.path} is damaged: {'; '.join(recording.damage)}; exporting what it holds")
    written = write_tables(tables(recorded_signals(recording)), out_path)
    say(f"wrote {', '.join(map(str, written))}")
    return 0


def add_parsers(commands) -> None:
    replay = commands.add_parser(
        "replay", help="replay a recording in Rerun, or verify it by re-running its scene",
        **examples("zencosim replay run.mcap --verify", "zencosim replay run.mcap --rrd run.rrd   # zencosim[rerun]"))
    replay.add_argument("recording", help="an MCAP file written by 'zencosim run --record'")
    replay.add_argument("--rrd", metavar="FILE", help="write a Rerun recording (.rrd)")
    replay.add_argument("--spawn", action="store_true", help="open a Rerun viewer with the recording")
    replay.add_argument("--verify", action="store_true",
                        help="re-run the embedded scene in process and compare every channel bit for bit")
    replay.set_defaults(handler=cmd_replay)

    inspect = commands.add_parser("inspect", help="show what a recording holds", **examples("zencosim inspect run.mcap"))
    inspect.add_argument("recording", help="an MCAP file written by 'zencosim run --record'")
    inspect.set_defaults(handler=cmd_inspect)

    export = commands.add_parser(
        "export", help="write a recording's signals as tables (CSV, NPZ, Parquet), as 'run --out' does",
        **examples("zencosim export run.mcap --out results.csv", "zencosim export run.mcap --out results.npz"))
    export.add_argument("recording", help="an MCAP file written by 'zencosim run --record'")
    export.add_argument("--out", required=True, metavar="FILE",
                        help="where to write (.csv, .npz, .parquet); a multi-rate run gives one file per communication step")
    export.set_defaults(handler=cmd_export)
