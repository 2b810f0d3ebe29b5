"""A subsystem process in lock step answers its zero-order STEPs by its step's statements
(``subsystems.process.endpoint.StatementSteps``): every reply byte for byte the one ``SubsystemEndpoint.handle``
gives a twin of the subsystem for the same commands — the small linear models' straight-line steps over generated
input values, the example C FMU's calls, its failure's ERROR reply — and, at the end, the subsystem in the twin's
state."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.subsystems.test_straight_line import LINEAR
from zencosim.manager.assembly import build_subsystems
from zencosim.manager.scene.load import load_scene
from zencosim.manager.wire.protocol import HEADER, VERSION, Kind, decode
from zencosim.subsystems.process.endpoint import SubsystemEndpoint


def _twins(scene: str, name: str, overrides: list[str]) -> tuple[SubsystemEndpoint, SubsystemEndpoint, int]:
    loaded = load_scene(scene, overrides)
    base = loaded.manager.macro_step_ns
    return (*(SubsystemEndpoint(build_subsystems(load_scene(scene, overrides))[name], 1, base) for _ in range(2)),
            base)


def _command(tick: int, base_ns: int, values: list[float]) -> bytes:
    return HEADER.pack(VERSION, Kind.STEP, 1, len(values), tick, tick * base_ns, 0) + struct.pack(
        f"<{len(values)}d", *values)


def _same_replies(statements_of: SubsystemEndpoint, twin: SubsystemEndpoint, base_ns: int, inputs: list[list[float]]
                  ) -> list[bytes]:
    steps = statements_of.zero_order_steps()
    assert steps is not None
    replies = []
    for tick, values in enumerate(inputs):
        command = _command(tick, base_ns, values)
        replies.append(steps.answer(tick, command))
        assert replies[-1] == twin.handle(command), tick
        if replies[-1][1] == Kind.ERROR:  # the run ends there: no process is sent another command
            return replies
    steps.end(len(inputs))
    return replies


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(LINEAR), st.sampled_from([1, 4]), st.data())
def test_a_linear_subsystems_statements_answer_as_its_endpoint_does_byte_for_byte(scene_name, micro_steps, data):
    scene, name = scene_name
    macro_step = load_scene(scene).manager.macro_step
    ours, twin, base = _twins(scene, name, [f"subsystems.{name}.micro_step={macro_step / micro_steps!r}"])
    width = len(ours.subsystem.inputs)
    value = st.floats(-1e6, 1e6, allow_nan=False) | st.sampled_from([0.0, -0.0, 1e300, np.nan, np.inf])
    inputs = data.draw(st.lists(st.lists(value, min_size=width, max_size=width), min_size=1, max_size=40))
    with np.errstate(over="ignore", invalid="ignore"):
        _same_replies(ours, twin, base, inputs)
    assert ours.subsystem.z.tobytes() == twin.subsystem.z.tobytes()
    assert ours.subsystem.t_ns == twin.subsystem.t_ns == len(inputs) * base
    assert np.array_equal(ours.subsystem.w, twin.subsystem.w, equal_nan=True)


@pytest.mark.parametrize("fail_at", [None, 0.0305])
def test_an_fmus_calls_answer_as_its_endpoint_does_and_its_failure_with_the_same_error(examples, fail_at):
    """The example C FMU (mass 2 of two_mass_damped), and the same FMU whose doStep fails from t = 30.5 ms."""
    scene = examples / "two_mass_damped_fmu.toml"
    if fail_at is not None:
        text = scene.read_text()
        scene = examples / "failing_fmu.toml"
        scene.write_text(text.replace("start = { m = 1.0, k = 1000.0,", f"start = {{ fail_at = {fail_at}, m = 1.0, "
                                      "k = 1000.0,"))
    ours, twin, base = _twins(str(scene), "S2", [])
    inputs = [[np.sin(0.1 * tick), np.cos(0.1 * tick)][:len(ours.subsystem.inputs)] for tick in range(50)]
    replies = _same_replies(ours, twin, base, inputs)
    kinds = [decode(reply, "S2").kind for reply in replies]
    if fail_at is None:
        assert kinds == [Kind.OUTPUT] * 50
        assert ours.subsystem.t_ns == twin.subsystem.t_ns == 50 * base
        assert np.array_equal(ours.subsystem.w, twin.subsystem.w)
    else:
        assert kinds == [Kind.OUTPUT] * 31 + [Kind.ERROR]  # the step from t = 31 ms
        assert "fmi2DoStep failed with status" in decode(replies[31], "S2").text()
