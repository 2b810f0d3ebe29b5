"""The typed message encoding: any protobuf runtime reads a channel's messages by the scene's signal names,
and every float64 value round-trips bit for bit through the vectorised encoder and our decoder."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from zencosim.manager.wire.protocol import Kind, encode, encode_error
from zencosim.recordings.encoding import BatchEncoder
from zencosim.recordings.layout import ChannelSpec
from zencosim.recordings.schema import ChannelSchema, decode

OUTPUTS = ChannelSpec("S2/y", "S2", "outputs", ("x2", "v2", "energy"), ("m", "m/s", "J"))
INPUTS = ChannelSpec("S1/commands", "S1", "inputs", ("x2*", "v2*"), ("m", "m/s"))
STATUS = ChannelSpec("manager/status", "manager", "status", ("delta_p.c", "delta_e.c", "wall_time"), ("W", "J", "s"),
                     ("wall_time",))
ANY_FLOAT64 = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)


def protobuf_class(schema: ChannelSchema):
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(schema.descriptor_set).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))


def encoded(spec: ChannelSpec, wires: list[bytes]) -> list[bytes]:
    """The protobuf message of each wire message of ``spec``'s channel, as the recorder encodes them."""
    schemas = [ChannelSchema(spec), ChannelSchema(STATUS)]
    batch = BatchEncoder(schemas, [1, 2], status=1).encode(
        np.zeros(len(wires), dtype=np.uint8), np.array([len(w) for w in wires]), np.zeros(0, dtype=np.int64),
        b"".join(wires), 7, str)
    assert not batch.malformed and batch.log_times.tolist() == [7] * len(wires)
    records = []
    for offset in batch.offsets.tolist():
        opcode, length, channel_id = struct.unpack_from("<BQH", batch.records, offset)
        assert (opcode, channel_id) == (0x05, 1)
        records.append(batch.records[offset + 9 + 22:offset + 9 + length].tobytes())
    return records


@settings(max_examples=100, deadline=None)
@given(values=arrays(np.float64, 3, elements=ANY_FLOAT64), step=st.integers(-1, 2**40), time_ns=st.integers(-1, 2**52))
def test_outputs_are_fields_named_as_the_signals_bit_for_bit(values, step, time_ns):
    schema = ChannelSchema(OUTPUTS)
    wire = encode(Kind.OUTPUT, step, time_ns, values, ref=0xDEADBEEF)
    (data,) = encoded(OUTPUTS, [wire])
    parsed = protobuf_class(schema).FromString(data)
    assert (parsed.step, parsed.time_ns, parsed.kind, parsed.ref) == (step, time_ns, Kind.OUTPUT, 0xDEADBEEF)
    assert parsed.DESCRIPTOR.enum_types_by_name == {} and parsed.DESCRIPTOR.fields_by_name["kind"].enum_type.values_by_number[
        Kind.OUTPUT].name == "KIND_OUTPUT"
    assert np.array([parsed.x2, parsed.v2, parsed.energy]).tobytes() == values.tobytes()
    ours = decode(parsed.SerializeToString(), schema)  # the runtime's own encoding, read back by ours
    assert (ours.step, ours.time_ns, ours.kind, ours.ref) == (step, time_ns, Kind.OUTPUT, 0xDEADBEEF)
    assert ours.values.tobytes() == values.tobytes()


@settings(max_examples=50, deadline=None)
@given(rows=st.integers(1, 3), data=st.data())
def test_a_command_holds_each_input_as_its_polynomial_coefficients(rows, data):
    values = data.draw(arrays(np.float64, (rows, 2), elements=ANY_FLOAT64))
    schema = ChannelSchema(INPUTS)
    assert schema.field_names == ("x2", "v2")  # x2* is the received x2
    (message,) = encoded(INPUTS, [encode(Kind.STEP, 4, 4_000_000, values, rows=rows)])
    parsed = protobuf_class(schema).FromString(message)
    assert np.array(parsed.x2).tobytes() == values[:, 0].tobytes()
    assert np.array(parsed.v2).tobytes() == values[:, 1].tobytes()
    assert decode(message, schema).values.tobytes() == values.tobytes()


def test_status_fields_nest_by_their_prefix_and_carry_units_in_the_schema():
    schema = ChannelSchema(STATUS)
    (message,) = encoded(STATUS, [encode(Kind.STATUS, 9, 9_000_000, np.array([1.5, -0.0, 2.0]))])
    parsed = protobuf_class(schema).FromString(message)
    assert (parsed.delta_p.c, parsed.delta_e.c, parsed.wall_time) == (1.5, 0.0, 2.0)
    assert decode(message, schema).values.tobytes() == np.array([1.5, -0.0, 2.0]).tobytes()
    files = descriptor_pb2.FileDescriptorSet.FromString(schema.descriptor_set).file
    comments = [location.trailing_comments for location in files[-1].source_code_info.location]
    assert sorted(comments) == [" [J]", " [W]", " [s]"]


def test_messages_outside_the_named_layout_error_text_and_empty_messages_round_trip():
    schema = ChannelSchema(INPUTS)
    project = encode(Kind.PROJECT, 3, 3, np.array([0.5, -1.0, np.nan, 2.0]))  # corrections: values
    save, error = encode(Kind.SAVE, 3, 3), encode_error(-1, -1, "ValueError: bad ü")
    decoded = [decode(m, schema) for m in encoded(INPUTS, [project, save, error])]
    assert decoded[0].values.tobytes() == np.array([0.5, -1.0, np.nan, 2.0]).tobytes() and decoded[0].kind == Kind.PROJECT
    assert decoded[1].values.size == 0 and decoded[1].kind == Kind.SAVE
    assert decoded[2].text == "ValueError: bad ü" and decoded[2].step == -1 and decoded[2].kind == Kind.ERROR


def test_a_malformed_message_is_described_and_left_out():
    schemas = [ChannelSchema(OUTPUTS), ChannelSchema(STATUS)]
    good = encode(Kind.OUTPUT, 1, 1, np.arange(3.0))
    bad = bytes([9]) + good[1:]
    batch = BatchEncoder(schemas, [1, 2], status=1).encode(np.zeros(2, dtype=np.uint8), np.array([len(bad), len(good)]),
                                                           np.zeros(0, dtype=np.int64), bad + good, 0,
                                                           lambda i: f"message {i}")
    assert batch.malformed == ["message from message 0: protocol version 9, expected 2"]
    assert batch.offsets.tolist() == [0]


def test_a_truncated_message_is_rejected():
    (data,) = encoded(OUTPUTS, [encode(Kind.OUTPUT, 3, 3, np.arange(3.0))])
    for cut in (5, len(data) - 4):  # inside the step field, inside the values
        with pytest.raises(ValueError, match="truncated"):
            decode(data[:cut], ChannelSchema(OUTPUTS))


@pytest.mark.parametrize("varint, reason", [(bytes([0xFF] * 9 + [0x7F]), "a varint beyond 64 bits"),
                                            (bytes([0xFF] * 12 + [0x01]), "a varint of more than 10 bytes")])
def test_a_varint_no_64_bit_field_holds_is_a_damaged_message(varint, reason):
    # damaged bytes can make the step's varint as long as they like: it must not reach numpy's int64 arrays
    # (an OverflowError there ended zencosim inspect in a traceback)
    with pytest.raises(ValueError, match=reason):
        decode(bytes([0x08]) + varint)


@st.composite
def batches(draw) -> tuple[list[int], list[bytes]]:
    """Messages of the three channels of this file: a few exchanges repeated (the rows of each channel then lie
    evenly spaced, as in a run's steady batches), or channels in any order; values of every kind."""
    def message(channel: int, step: int) -> bytes:
        if channel == 0:
            if draw(st.integers(0, 9)) == 0:  # now and then a subsystem's ERROR, encoded on its own
                return encode_error(step, step * 1000, draw(st.text(max_size=30)))
            return encode(Kind.OUTPUT, step, step * 1000, draw(arrays(np.float64, 3, elements=ANY_FLOAT64)))
        if channel == 1:
            rows = draw(st.integers(1, 3))
            return encode(Kind.STEP, step, step * 1000, draw(arrays(np.float64, (rows, 2), elements=ANY_FLOAT64)),
                          rows)
        return encode(Kind.STATUS, step, step * 1000, draw(arrays(np.float64, 3, elements=ANY_FLOAT64)))
    if draw(st.booleans()):
        pattern = draw(st.lists(st.integers(0, 2), min_size=1, max_size=4))
        order = pattern * draw(st.integers(1, 6))
    else:
        order = draw(st.lists(st.integers(0, 2), max_size=20))
    return order, [message(channel, step) for step, channel in enumerate(order)]


@settings(max_examples=150, deadline=None)
@given(batches())
def test_a_batch_holds_each_message_encoded_alone(batch):
    """The encoder groups a batch's messages by layout, gathers each group's bytes and scatters its records back into
    the batch's order (``recordings.encoding``): the records are, byte for byte and in that order, those of the
    messages encoded one at a time, each with the log time it has in the batch."""
    order, wires = batch
    schemas = [ChannelSchema(OUTPUTS), ChannelSchema(INPUTS), ChannelSchema(STATUS)]
    whole = BatchEncoder(schemas, [1, 2, 3], status=2).encode(
        np.array(order, dtype=np.uint8), np.array([len(w) for w in wires], dtype=np.int64),
        np.arange(order.count(2), dtype=np.int64) * 10 + 100, b"".join(wires), 7, str)
    assert whole.channels.tolist() == order
    starts = whole.offsets.tolist()
    for channel, wire, log_time, start, end in zip(order, wires, whole.log_times.tolist(), starts,
                                                    [*starts[1:], whole.records.size]):
        alone = BatchEncoder(schemas, [1, 2, 3], status=2).encode(
            np.array([channel], dtype=np.uint8), np.array([len(wire)]),
            np.array([log_time] if channel == 2 else [], dtype=np.int64), wire, log_time, str)
        assert alone.log_times.tolist() == [log_time]
        assert whole.records[start:end].tobytes() == alone.records.tobytes()
