"""A recording whose subsystems' reply channels were swapped (rewritten with the mcap library: every message kept,
S1/y and S2/y exchanged) is named as such by export, replay --verify and inspect: one line, no traceback."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

SWAP = {"S1/y": "S2/y", "S2/y": "S1/y"}


def swapped_copy(source: Path, target: Path) -> Path:
    with open(source, "rb") as f, open(target, "wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        header = reader.get_header()
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(header.profile, header.library)
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {}
        for cid, channel in sorted(summary.channels.items()):
            topic = next((channel.topic[:-len(a)] + b for a, b in SWAP.items() if channel.topic.endswith(a)),
                         channel.topic)
            channels[cid] = writer.register_channel(topic, channel.message_encoding, schemas.get(channel.schema_id, 0),
                                                    channel.metadata)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time,
                               message.sequence)
        for attachment in reader.iter_attachments():
            writer.add_attachment(attachment.create_time, attachment.log_time, attachment.name, attachment.media_type,
                                  attachment.data)
        for metadata in reader.iter_metadata():
            writer.add_metadata(metadata.name, metadata.metadata)
        writer.finish()
    return target


@pytest.fixture(scope="module")
def swapped(tmp_path_factory) -> Path:
    directory = tmp_path_factory.mktemp("swapped")
    recording = directory / "run.mcap"
    subprocess.run([sys.executable, "-m", "zencosim", "run", "two_mass_damped", "--set", "manager.duration=0.05",
                    "--record", str(recording), "--quiet"], check=True, timeout=300)
    return swapped_copy(recording, directory / "swapped.mcap")


@pytest.mark.multiprocess
@pytest.mark.parametrize("command", [["export", "--out", "OUT"], ["replay", "--verify"]])
def test_swapped_reply_channels_are_named_not_a_traceback(swapped, command):
    arguments = [str(swapped.with_name("out.csv")) if a == "OUT" else a for a in command]
    run = subprocess.run([sys.executable, "-m", "zencosim", command[0], str(swapped), *arguments[1:]],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode in (1, 2) and "Traceback" not in run.stderr, run.stderr
    assert "channel S1/y holds x2, v2, energy" in run.stderr and "fc, energy" in run.stderr
