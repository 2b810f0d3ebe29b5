"""The generated macro-step loop (``manager.scheme.compiled``): a single-rate, zero-order run of straight-line
subsystems computes every array of the generic Jacobi loop bit for bit, leaves the subsystems where it leaves them,
reports progress as it does, and is taken where it may be taken only.

The oracle is the generic loop on the same scene (``compiled_steps`` patched to give None), whose equality with the
message path and with a Zenoh run tests/manager/test_direct.py and tests/manager/test_buses.py check."""
from __future__ import annotations

import signal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import zencosim.manager.bus.inproc as inproc_module
import zencosim.manager.scheme.compiled as compiled_module
import zencosim.manager.scheme.jacobi as jacobi_module
import zencosim.manager.scheme.register_loop as register_loop_module
import zencosim.subsystems.models.external.fmu as fmu_module
from tests.manager.frames_recorder import FramesRecorder
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.bus.inproc import DirectCalls, run_in_process
from zencosim.manager.bus.watchdog import CALLS, SUBSYSTEM, T_NS, ModelWatch
from zencosim.manager.results.summary import digest
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.scheme.compiled import compiled_steps
from zencosim.manager.scheme.register_loop import register_loop
from zencosim.manager.scheme.residual import residual_power, residual_power_text
from zencosim.manager.wire.protocol import HEADER, decode
from zencosim.manager.wire.status import StatusReport

# the bundled scenes the generated loop runs (single-rate, ZOH, linear subsystems), and a few it must not
COMPILED = ["two_mass_damped", "two_mass_undamped", "four_mass", "mass_chain", "multiple_oscillator_n3",
            "multiple_oscillator_n5", "double_oscillator"]
GENERIC = {"FOH": ("two_mass_damped", ["manager.extrapolation=1"]),
           "multi-rate": ("double_oscillator", ["manager.macro_step=0.0001", "subsystems.M1.comm_ratio=10",
                                                "subsystems.M2.micro_step=0.0001"]),
           "nonlinear": ("hydraulic_crane", []),
           "input table": ("two_mass_chirp", [])}


@pytest.fixture(params=["registers", "python"])
def loop(request, monkeypatch):
    """The generated loop of straight-line steps run as a register program in C (``register_loop``: there must be a
    C compiler, as for the example FMUs) or as the Python loop itself; each run of it was the one asked for."""
    made = _programs(request.param == "registers", monkeypatch)
    yield request.param
    assert all(program is not None for program in made) and bool(made) == (request.param == "registers")


def _programs(registers: bool, monkeypatch) -> list:
    """The generated loop as a register program where it can be one (``registers``), else as the Python loop; the
    register programs made are noted in the list returned."""
    made = []

    def noted(*args):
        made.append(register_loop(*args))
        return made[-1]
    monkeypatch.setattr(compiled_module, "register_loop", noted)
    monkeypatch.setattr(compiled_module, "REGISTER_LOOP", registers)
    return made


def _run(name: str, overrides: list[str], compiled: bool, monkeypatch, keep: bool | None = None, progress=None):
    """A direct run of the scene, by the generated loop or (``compiled`` False) the generic one: (record, subsystems,
    whether the generated loop ran)."""
    ran = []

    scene = load_scene(name, overrides)
    plan, subsystems = plan_scene(scene)
    with monkeypatch.context() as patched:
        patched.setattr(jacobi_module, "compiled_steps", _spied(compiled, ran))
        scheme = make_scheme(scene, plan, progress=progress, keep=keep, direct=DirectCalls(plan, subsystems))
        with np.errstate(over="ignore", invalid="ignore"):
            record = run_in_process(scheme, plan, subsystems)
    return record, subsystems, ran == [True]


def _spied(compiled: bool, ran: list[bool]):
    """``compiled_steps`` for a run: the generated loop (``compiled``) or none, noting in ``ran`` whether one ran."""
    def spied(plan, direct, commands):
        steps = compiled_steps(plan, direct, commands) if compiled else None
        ran.append(steps is not None)
        return steps
    return spied


def _assert_same_run(ours, theirs) -> None:
    """Every array of the two records and the subsystems' state at the end, bit for bit."""
    (record, subsystems), (expected, expected_subsystems) = ours, theirs
    assert digest(record) == digest(expected)
    for mine, other in zip(record.trajectories, expected.trajectories):
        assert np.array_equal(mine, other, equal_nan=True)
    assert np.array_equal(record.residual_power, expected.residual_power, equal_nan=True)
    assert np.array_equal(record.residual_energy, expected.residual_energy, equal_nan=True)
    assert record.send_time_ns.shape == expected.send_time_ns.shape
    assert (np.diff(record.send_time_ns) >= 0).all() and (record.send_time_ns > 0).all()
    for name, subsystem in subsystems.items():
        other = expected_subsystems[name]
        assert subsystem.t_ns == other.t_ns
        assert np.array_equal(subsystem.z, other.z, equal_nan=True)
        assert np.array_equal(np.asarray(subsystem.w, dtype=float), np.asarray(other.w, dtype=float), equal_nan=True)


@pytest.mark.parametrize("name, scheme", [*((name, "jacobi") for name in COMPILED),
                                          ("two_mass_damped", "gauss-seidel"), ("mass_chain", "gauss-seidel")])
def test_the_generated_loop_computes_the_generic_loops_arrays_bit_for_bit(name, scheme, loop, monkeypatch):
    overrides = ["manager.duration=1.2", f"manager.scheme={scheme}"]  # 1,200 steps or more: blocks of 500
    record, subsystems, compiled = _run(name, overrides, True, monkeypatch)
    expected, expected_subsystems, generic_compiled = _run(name, overrides, False, monkeypatch)
    assert compiled and not generic_compiled
    _assert_same_run((record, subsystems), (expected, expected_subsystems))


def test_a_long_run_spilled_to_files_is_the_same(loop, monkeypatch):
    """Past the windows' memory (spilled every 8,192 rows) the generated loop's rows land where the generic loop's do;
    and progress is reported at the same steps."""
    overrides = ["manager.duration=20.0"]
    seen, expected_seen = [], []
    record, subsystems, compiled = _run("two_mass_damped", overrides, True, monkeypatch, keep=False,
                                        progress=seen.append)
    expected, expected_subsystems, _ = _run("two_mass_damped", overrides, False, monkeypatch, keep=False,
                                            progress=expected_seen.append)
    assert compiled
    _assert_same_run((record, subsystems), (expected, expected_subsystems))
    assert seen == expected_seen == list(range(500, 20_001, 500))


@pytest.mark.parametrize("case", GENERIC)
def test_scenes_the_generated_loop_cannot_run_take_the_generic_loop(case, monkeypatch):
    name, overrides = GENERIC[case]
    _, _, compiled = _run(name, overrides + ["manager.duration=0.1"], True, monkeypatch)
    assert not compiled


@st.composite
def linear_chains(draw) -> list[str]:
    """mass_chain with drawn masses, springs, dampers and couplings (stable and unstable co-simulations both)."""
    scene = load_scene("mass_chain")
    value = st.floats(0.1, 10.0)
    overrides = ["manager.duration=0.6"]
    for name, doc in scene.resolved["subsystems"].items():
        for body in doc.get("bodies", {}):
            overrides.append(f"subsystems.{name}.bodies.{body}.mass={draw(value)!r}")
        for effect, spec in doc.get("effects", {}).items():
            key = "stiffness" if spec["type"] == "spring" else "damping"
            overrides.append(f"subsystems.{name}.effects.{effect}.{key}={100 * draw(value)!r}")
    for name, doc in scene.resolved["couplings"].items():
        for effect, spec in doc.get("effects", {}).items():
            key = "stiffness" if spec["type"] == "spring" else "damping"
            overrides.append(f"couplings.{name}.effects.{effect}.{key}={100 * draw(value)!r}")
    return overrides


@pytest.mark.parametrize("registers", [True, False], ids=["registers", "python"])
@settings(max_examples=15, deadline=None)
@given(linear_chains())
def test_on_generated_chains_the_generated_loop_is_the_generic_loop_bit_for_bit(registers, overrides):
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(compiled_module, "REGISTER_LOOP", registers)
        ours = _run("mass_chain", overrides, True, monkeypatch)
        theirs = _run("mass_chain", overrides, False, monkeypatch)
    assert ours[2]
    _assert_same_run(ours[:2], theirs[:2])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=4, max_size=4))
def test_the_residual_powers_text_is_its_function_bit_for_bit(values):
    names = ("f", "v_in", "f_in", "v")
    evaluated = eval(residual_power_text(*names), {}, dict(zip(names, values)))  # our own text
    expected = residual_power(*values)
    assert np.array_equal(np.float64(evaluated), np.float64(expected), equal_nan=True)
    assert np.signbit(evaluated) == np.signbit(expected)


def test_a_recorded_run_is_run_by_the_generated_loop_with_the_generic_loops_messages(loop, monkeypatch):
    """With a status and a recorder's tap of blocks (``TakenSteps``) the generated loop runs the steps, and the
    recorder gets every message of the generic loop (each status's residuals included, not its wall times), in
    order, in the same frames; its statuses' wall times are the steps' own (a step completes before the next is
    released)."""
    seen, ran = [], []
    for compiled in (True, False):
        scene = load_scene("two_mass_damped", ["manager.duration=4.5"])  # blocks of 2,000 steps and a shorter one
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        recorder = FramesRecorder(plan, status)
        with monkeypatch.context() as patched:
            patched.setattr(jacobi_module, "compiled_steps", _spied(compiled, ran))
            run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems),
                                       tap=recorder), plan, subsystems, recorder)
        recorder.flush(last=True)
        seen.append(recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)))
        if compiled:
            statuses = [decode(data, "status").values.tolist() for i, data in recorder.messages(None)
                        if i == recorder._status]
    assert ran == [True, False]
    assert len(seen[0]) > 3 * 4500 and seen[0] == seen[1]
    wall, step_wall = np.array([values[2:4] for values in statuses]).T
    assert len(wall) == 4500 and (np.diff(wall) >= 0).all() and (step_wall >= 0).all() and (step_wall <= wall).all()


def _fmi_calls(calls: str, monkeypatch) -> list:
    """The generated loop makes an FMU's step one call of the compiled ``fmi2_steps_run`` or ``fmi3_steps_run``
    (there must be a C compiler, as for the example FMUs): from the register program (``"in C"``,
    ``register_loop``'s native step) or from the Python loop (``"one call"``); or, where none is found
    (``"one by one"``), the Python loop makes a ctypes call per FMI call for FMI 2.0, and FMI 3.0 FMUs step in the
    scheme's own loop. A register program with native steps ends a block of steps once they have taken its time
    budget (slow models' steps): ``"in C, a step a block"`` gives it a budget that every step exceeds. Returns the
    register programs made (:func:`_programs`)."""
    if calls == "one by one":
        monkeypatch.setattr(fmu_module, "steps_function", lambda version: None)
    else:
        assert fmu_module.steps_function("2") is not None and fmu_module.steps_function("3") is not None
    if calls == "in C, a step a block":
        monkeypatch.setattr(register_loop_module, "BUDGET_NS", -1)
    return _programs(calls.startswith("in C"), monkeypatch)


FMI_CALLS = ["in C", "in C, a step a block", "one call", "one by one"]


FOUR_MICRO_STEPS = ["subsystems.S1.micro_step=0.00025"]


@pytest.mark.parametrize("calls", FMI_CALLS)
@pytest.mark.parametrize("name, overrides", [("two_mass_damped_fmu", []), ("double_oscillator_fmu", []),
                                             ("two_mass_damped_fmu", FOUR_MICRO_STEPS), ("two_mass_damped_fmu3", []),
                                             ("two_mass_damped_fmu3", FOUR_MICRO_STEPS)],
                         ids=["two_mass_damped_fmu", "double_oscillator_fmu", "four micro-steps", "FMI 3.0",
                              "FMI 3.0, four micro-steps"])
def test_co_simulation_fmus_step_in_the_generated_loop_as_in_the_generic_one(examples, name, overrides, calls,
                                                                             monkeypatch):
    """The example C FMUs' calls (set, step at the same times, get) written into the loop, as one call or a call
    each, from the register program or the Python loop: the same arrays. An FMI 3.0 FMU without the compiled call
    steps in the scheme's own loop."""
    scene, overrides = str(examples / f"{name}.toml"), ["manager.duration=1.2", *overrides]
    expected, expected_subsystems, _ = _run(scene, overrides, False, monkeypatch)
    made = _fmi_calls(calls, monkeypatch)
    record, subsystems, compiled = _run(scene, overrides, True, monkeypatch)
    assert compiled == (calls != "one by one" or not name.endswith("fmu3"))
    assert all(program is not None for program in made) and len(made) == calls.startswith("in C")
    _assert_same_run((record, subsystems), (expected, expected_subsystems))


def test_a_watched_run_marks_every_fmu_step_that_the_register_program_makes(examples, monkeypatch):
    """In a watched run (the command line's in-process run, ``manager.bus.watchdog``) the register program still makes
    the FMUs' steps and marks each on the watch's page as the Python loop's statements mark it: as many calls, the
    last from the same start, no subsystem in a call at the end; and the same arrays."""
    scene, overrides = str(examples / "two_mass_damped_fmu.toml"), ["manager.duration=1.2"]
    runs, pages = [], []
    for calls in ("in C", "one call"):
        with monkeypatch.context() as patched:
            watch = ModelWatch(shared=True)
            watch.start(["S1", "S2"], 10.0)
            patched.setattr(inproc_module, "model_watch", lambda: watch)
            made = _fmi_calls(calls, patched)
            record, subsystems, compiled = _run(scene, overrides, True, patched)
        assert compiled and len(made) == (calls == "in C") and all(program is not None for program in made)
        runs.append((record, subsystems))
        pages.append([watch.slots[slot] for slot in (SUBSYSTEM, CALLS, T_NS)])
    assert pages[0] == pages[1] and pages[0][0] == -1 and pages[0][1] > 2 * 1200, pages
    _assert_same_run(*runs)


@pytest.mark.parametrize("calls", FMI_CALLS)
@pytest.mark.parametrize("version", ["2", "3"])
@pytest.mark.parametrize("fail_at, duration", [(0.7005, 1.2), (0.0, 0.1)], ids=["mid-run", "first step"])
def test_a_failing_fmu_ends_the_generated_loop_as_it_ends_the_generic_one(examples, fail_at, duration, version, calls,
                                                                          monkeypatch):
    """An FMU whose step fails at ``fail_at`` (the example's parameter): the same one line (the subsystem, the
    step, the FMI call, its status, the time) and a recording of each holds the same messages, up to the failing
    step's commands."""
    text = (examples / f"two_mass_damped_fmu{'3' if version == '3' else ''}.toml").read_text()
    failing = examples / "failing_fmu.toml"
    failing.write_text(text.replace("start = { m = 1.0, k = 1000.0,", f"start = {{ fail_at = {fail_at}, m = 1.0, "
                                    "k = 1000.0,"))
    said, recorded, ran = [], [], []
    made = _fmi_calls(calls, monkeypatch)
    for compiled in (True, False):
        scene = load_scene(str(failing), [f"manager.duration={duration}"])
        plan, subsystems = plan_scene(scene)
        status = StatusReport(plan, False)
        recorder = FramesRecorder(plan, status)
        with monkeypatch.context() as patched, pytest.raises(SubsystemFailure) as failure:
            patched.setattr(jacobi_module, "compiled_steps", _spied(compiled, ran))
            run_in_process(make_scheme(scene, plan, status=status, direct=DirectCalls(plan, subsystems),
                                       tap=recorder), plan, subsystems, recorder)
        recorder.flush(last=True)
        said.append(str(failure.value))
        recorded.append(recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)))
    assert ran == [calls != "one by one" or version == "2", False]
    assert all(program is not None for program in made) and len(made) == calls.startswith("in C")
    assert said[0] == said[1] and said[0].startswith("subsystem S2: failed at step "), said
    assert f"fmi{version}DoStep failed with status" in said[0]
    assert recorded[0] == recorded[1] and len(recorded[0]) >= 4


def _recorded_until_interrupted(compiled: bool, monkeypatch, ran: list, progress=None, steps=None) -> tuple[list, int]:
    """What a recorder gets from a 4.5 s run of two_mass_damped by the generated loop (``compiled``) or the generic
    one, which a KeyboardInterrupt from ``progress`` or from ``steps`` (``RegisterLoop.steps`` patched) ends, and
    the index of S1's commands channel."""
    scene = load_scene("two_mass_damped", ["manager.duration=4.5"])
    plan, subsystems = plan_scene(scene)
    status = StatusReport(plan, False)
    recorder = FramesRecorder(plan, status)
    with monkeypatch.context() as patched, pytest.raises(KeyboardInterrupt):
        patched.setattr(jacobi_module, "compiled_steps", _spied(compiled, ran))
        if steps is not None:
            patched.setattr(register_loop_module.RegisterLoop, "steps", steps)
        run_in_process(make_scheme(scene, plan, status=status, progress=progress,
                                   direct=DirectCalls(plan, subsystems), tap=recorder), plan, subsystems, recorder)
    recorder.flush(last=True)
    return recorder.messages(HEADER.size + 8 * 2 * len(plan.bonds)), recorder._index["S1", "commands"]


def test_an_interrupt_during_a_register_block_hands_over_the_steps_the_block_ran(monkeypatch):
    """A SIGINT that arrives while a block of the register program runs in C is raised as the call returns (here: sent
    as the block of steps 1000 … 1499 returns): the recorder gets every step the block ran, the same messages as a
    generic loop interrupted after step 1500."""
    blocks, ran = [], []
    steps = register_loop_module.RegisterLoop.steps

    def interrupted(self, first: int, count: int):
        done = steps(self, first, count)
        blocks.append(first)
        if first == 1000:
            signal.raise_signal(signal.SIGINT)
        return done

    def progress(tick: int) -> None:
        if tick == 1500:
            raise KeyboardInterrupt
    recorded, commands = _recorded_until_interrupted(True, monkeypatch, ran, steps=interrupted)
    expected, _ = _recorded_until_interrupted(False, monkeypatch, ran, progress=progress)
    assert ran == [True, False] and blocks == [0, 500, 1000]  # the register program was interrupted in its third block
    assert recorded == expected
    assert sum(i == commands for i, _ in recorded) == 1500 + 1


@pytest.mark.parametrize("at", [500, 2500], ids=["first block", "second block"])
def test_an_interrupted_recorded_run_hands_the_recorder_what_the_generic_loop_hands_it(at, loop, monkeypatch):
    """An interrupt between two steps (from the progress report after step ``at``; blocks of 2,000 steps): the
    recorder gets the same messages from the generated loop's rows as from the generic loop, up to the commands of
    the last request, whose replies the scheme took but never handed over."""
    ran = []

    def progress(tick: int) -> None:
        if tick == at:
            raise KeyboardInterrupt
    recorded, commands = _recorded_until_interrupted(True, monkeypatch, ran, progress)
    expected, _ = _recorded_until_interrupted(False, monkeypatch, ran, progress)
    assert ran == [True, False]
    assert recorded == expected
    assert sum(i == commands for i, _ in recorded) == at + 1  # the initialisation's INIT and the steps' STEPs
