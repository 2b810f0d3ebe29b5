"""A channel's messages decoded a block at a time (``recordings.decoding``) are the messages the generic protobuf
decoder gives one by one, bit for bit — for every channel of recordings of the schemes' kinds of messages — and
a message the block decoder cannot place is decoded generically, not dropped or misread."""
from __future__ import annotations

import numpy as np
import pytest

import zencosim
from zencosim.recordings.decoding import decode_messages, same_message
from zencosim.recordings.mcap_read import McapScan
from zencosim.recordings.reader import read_recording
from zencosim.recordings.schema import decode

RUNS = {  # what their channels hold
    "two_mass_damped_foh": ("two_mass_damped", ["manager.extrapolation=1"]),  # polynomial commands, status groups
    "hydraulic_crane": ("hydraulic_crane", ["manager.duration=0.1"]),  # multi-rate, INIT and STEP of one length
    "constrained_two_mass": ("constrained_two_mass", ["manager.duration=0.05"]),  # SAVE, RESTORE, ACK
    # PROJECT: values the named fields do not describe, one packed run of doubles
    "constrained_two_mass_projection": ("constrained_two_mass", ["manager.duration=0.05",
                                                                 "manager.implicit.method=projection",
                                                                 "couplings.joint.decomposition=force-displacement"]),
}


def _raw(path) -> dict[str, list[bytes]]:
    """Every channel's message bodies, in order, as the file holds them."""
    from mcap.records import Channel, Message
    data = path.read_bytes()
    topics, bodies = {}, {}
    for _, record in McapScan(data).records():
        if isinstance(record, Channel):
            topics[record.id] = record.topic
        elif isinstance(record, Message):
            bodies.setdefault(topics[record.channel_id], []).append(record.data)
    return bodies


@pytest.mark.parametrize("run", RUNS)
def test_block_decoding_is_the_generic_decoding_of_every_message(run, tmp_path):
    name, overrides = RUNS[run]
    path = tmp_path / f"{run}.mcap"
    zencosim.run(zencosim.load_scene(name, overrides), record=path)
    recording = read_recording(path)
    for topic, bodies in _raw(path).items():
        schema = recording.channels[topic].schema
        generic = [decode(body, schema) for body in bodies]
        assert all(same_message(a, b) for a, b in zip(decode_messages(bodies, schema), generic, strict=True)), topic
        assert all(same_message(a, b) for a, b in zip(recording.channels[topic].messages, generic, strict=True)), topic


def test_a_message_off_the_layout_is_decoded_generically_and_a_damaged_one_is_its_error(tmp_path):
    """In a block of one length: a message whose constant bytes differ (another valid protobuf encoding: the
    step field written last) is decoded by the generic decoder to the same values; a truncated one is its error."""
    path = tmp_path / "run.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=0.01"]), record=path)
    recording = read_recording(path)
    bodies = _raw(path)["S2/y"]
    schema = recording.channels["S2/y"].schema
    reordered = bodies[3][9:] + bodies[3][:9]  # the step field (tag and 8 bytes) moved to the end
    truncated = bodies[4][:-3]  # the last value cut short
    decoded = decode_messages([*bodies[:3], reordered, truncated, *bodies[5:]], schema)
    assert same_message(decoded[3], decode(bodies[3], schema))
    assert isinstance(decoded[4], ValueError) and "truncated" in str(decoded[4])
    assert all(same_message(a, decode(b, schema)) for a, b in zip(decoded[5:], bodies[5:]))
    assert np.array_equal(recording.channels["S2/y"].messages[3].values, decoded[3].values)
