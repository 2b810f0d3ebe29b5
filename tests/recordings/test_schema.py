"""The stored message encoding: any protobuf runtime decodes it, and float64 values round-trip bit for bit."""
from __future__ import annotations

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from zencosim.manager.wire.protocol import Kind, encode, encode_error
from zencosim.recordings.schema import FILE_DESCRIPTOR_SET, SCHEMA_NAME, decode_stored, encode_wire


def _protobuf_class():
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(FILE_DESCRIPTOR_SET).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(SCHEMA_NAME))


MESSAGE = _protobuf_class()
ANY_FLOAT64 = arrays(np.float64, st.integers(0, 12), elements=st.floats(allow_nan=True, allow_infinity=True,
                                                                        allow_subnormal=True))


@settings(max_examples=200, deadline=None)
@given(values=ANY_FLOAT64, step=st.integers(-1, 2**40), time_ns=st.integers(-1, 2**62),
       kind=st.sampled_from([Kind.INIT, Kind.STEP, Kind.OUTPUT, Kind.STATUS]))
def test_the_protobuf_runtime_reads_every_value_bit_for_bit(values, step, time_ns, kind):
    # the bit patterns of NaN payloads, -0.0, infinities and subnormals all survive
    rows = 1 if kind in (Kind.INIT, Kind.STEP) else 0
    log_time, data = encode_wire(encode(kind, step, time_ns, values, rows=rows), "test")
    assert log_time == time_ns
    parsed = MESSAGE.FromString(data)
    assert (parsed.step, parsed.time_ns, parsed.kind, parsed.rows) == (step, time_ns, kind, rows)
    assert np.array(parsed.values, dtype="<f8").tobytes() == values.astype("<f8").tobytes()
    ours = decode_stored(parsed.SerializeToString())  # the runtime's own encoding, read back by ours
    assert (ours.step, ours.time_ns, ours.kind, ours.rows) == (step, time_ns, kind, rows)
    assert ours.values.tobytes() == values.astype("<f8").tobytes()


def test_error_text_and_empty_messages_round_trip():
    _, error = encode_wire(encode_error(-1, -1, "ValueError: bad ü"), "test")
    assert MESSAGE.FromString(error).text == "ValueError: bad ü"
    assert decode_stored(error).text == "ValueError: bad ü" and decode_stored(error).step == -1
    _, ack = encode_wire(encode(Kind.ACK, 5, 5_000_000), "test")
    assert decode_stored(ack).values.size == 0 and MESSAGE.FromString(ack).kind == Kind.ACK


def test_a_truncated_message_is_rejected():
    _, data = encode_wire(encode(Kind.OUTPUT, 3, 3, np.arange(3.0)), "test")
    for cut in (5, len(data) - 4):  # inside the step field, inside the values
        with pytest.raises(ValueError, match="truncated"):
            decode_stored(data[:cut])
