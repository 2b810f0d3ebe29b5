"""A single-rate, zero-order run whose subsystems' steps are statements, as one generated loop (issue 26).

When every subsystem of an in-process run (``manager.bus.inproc.DirectCalls``) has its step as statements
(``Subsystem.step_text``: a small linear model's straight-line step, ``subsystems.straight_line``, or a
co-simulation FMU's FMI calls), all at the base macro-step with zero-order inputs each fed once, one macro-step
of ``manager.scheme.jacobi`` is: every subsystem's inputs are its sources' newest outputs (paper 000 §2.1, ZOH),
each subsystem steps, its outputs are committed, and every bond's residual power and energy are evaluated
(paper 002 Eqs. 8–9, 13). This module writes that macro-step for the scene at hand as one Python loop over float
locals — the subsystems' step statements, their inputs read from the names that hold their sources' outputs,
each bond's δP and δE — and appends each step's row to one list. It is the scheme's arithmetic, operation for
operation: the statements ``Subsystem.advance_values`` runs (``Subsystem.step_text``), δP as
``residual_power`` adds it up, δE as the scheme accumulates it (with every bond evaluated at every step, its
``δP × (ticks since the last evaluation = 1) × step`` is ``δP × step``, bit for bit). The run's arrays and
digest are therefore the generic loop's and the message path's, bit for bit (tests/manager/test_compiled.py).

Gauss–Seidel runs the same way, stage after stage: a stage's commands are made from the newest outputs, those of
the stages before it already taken this step (``Plan.lead``), then its subsystems step.

Where every statement of a step is float arithmetic, or a subsystem's step is one call of a compiled function
(``StepText.native``: a co-simulation FMU's FMI calls, ``fmi_steps``), the same statements run as a register
program in C (``manager.scheme.register_loop``): the same operations on the same values, the same calls with the
same arguments. An in-process run of two_mass_damped takes about 1,700 instructions per macro-step, against 9,900
with the Python loop, and of two C FMUs about 1,500, against 14,800 with the Python loop and libcosim's 9,600
(valgrind). Without a C compiler the Python loop runs.

The loop runs in blocks that end where a progress report is due (``PROGRESS_EVERY``), in a recorded run where it
hands a recorder's tap a block (``manager.scheme.tapped``, every ``TAP_BLOCK_STEPS`` steps), and as a register
program with native steps also once its steps have taken the program's time budget (slow models' steps); after
each, the block's rows go to the run's windows (``manager.scheme.window``), the release times to the run's record,
and the rows with their times to the tap (``TakenRows``), from which the recorder's processes build the messages and
statuses the scheme's loop would have handed it: a recorded run's loop is the unrecorded one's. At the end the
subsystems take the state the loop left (``Subsystem.took_steps``).

Anything else runs the generic loop: multi-rate, polynomial inputs, correctors, pacing (a real-time run), a tap
that takes messages one by one, Gauss–Seidel with a tap, a subsystem that has no step as statements.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scheme.base import PROGRESS_EVERY, OutputReader, SubsystemCalls
from zencosim.manager.scheme.register_loop import NATIVE_CALL, STAMP_STATEMENT, NativeCall, register_loop
from zencosim.manager.scheme.residual import residual_power_text
from zencosim.manager.scheme.tapped import TakenRows
from zencosim.manager.scheme.window import RowWindow
from zencosim.manager.wire.arrays import float64s, int64s
from zencosim.subsystems.straight_line import StepText, define, unpacked

# steps in a block handed to a recorder's tap: a whole number of the loop's own blocks, which end where a progress
# report is due, so that the tap adds no block of its own (8 × 256 did, one per tap block: +13 % of the register
# loop's instructions per step, against +9 % now); about 2,000 steps, as many as 8 × BLOCK_STEPS were, where a
# generated loop's step cost an eighth of the scheme's loop's
TAP_BLOCK_STEPS = 4 * PROGRESS_EVERY
REGISTER_LOOP = True  # a loop of float arithmetic only runs as a register program in C (register_loop)


class CompiledSteps:
    """A scene's macro-steps as one generated loop (see the module text); ``run`` takes the place of the
    scheme's loop."""

    def __init__(self, plan: Plan, direct: SubsystemCalls, texts: list[StepText]) -> None:
        self.plan, self.direct, self.texts = plan, direct, texts
        self.width = [len(s.outputs) for s in plan.subsystems]
        self.output_ends = np.cumsum(self.width)
        self.bonds_start = int(self.output_ends[-1])  # the bonds' δP, then their δE
        self.row_width = self.bonds_start + 2 * len(plan.bonds)
        row = _row(plan, texts)
        self.natives = [i for i, text in enumerate(texts) if text.native is not None]  # their subsystems, in order
        natives = [NativeCall(texts[i].native, texts[i].coefficients, texts[i].outputs) for i in self.natives]
        self.registers = register_loop(self._initial(), _step_statements(plan, texts, self.natives), row, natives,
                                       plan.base_step_ns) if REGISTER_LOOP else None
        self.steps = None  # the Python loop, where there is no register program
        if self.registers is None:
            namespace = {"Stopped": Stopped}
            for text in texts:
                namespace.update(text.namespace)
            self.steps = define(_loop_text(plan, texts, _step_statements(plan, texts), row), "steps",
                                "<compiled macro-steps>", namespace)

    def _initial(self) -> list[str]:
        """The names that hold values before the first step: the state, the newest outputs, the bonds' energies."""
        return [name for t in self.texts for name in t.state] + [name for t in self.texts for name in t.outputs] \
            + _energies(self.plan)

    def run(self, readers: list[OutputReader], residual_power: RowWindow, residual_energy: RowWindow,
            release_times: RowWindow, progress: Callable[[int], None] | None, taken: TakenRows | None = None) -> int:
        """Run every macro-step from the outputs at t_0 the ``readers`` hold; fill their windows, the bonds' and the
        release times'; report progress and hand the tap its rows (``taken``) as the scheme hands it its blocks.
        Returns the number of macro-steps run (all). A step that raises (a model's failure, an interrupt) ends the
        run as the scheme's loop ends it: the steps before it handed over, the tap given its request, and the
        failure named as ``SubsystemCalls.step`` names it."""
        plan = self.plan
        n_ticks = plan.n_ticks
        state = [list(self.direct.state(s)) for s in plan.subsystems]
        newest = [list(reader.newest) for reader in readers]
        energies = [0.0] * len(plan.bonds)
        if taken is not None:
            taken.starts_from([y for outputs in newest for y in outputs], self.row_width)
        registers = self.registers
        if registers is not None:
            registers.set(self._initial(), [z for values in state for z in values]
                          + [y for values in newest for y in values] + energies)
        first = 0
        handover_at = taken.handed_over(time.perf_counter_ns(), TAP_BLOCK_STEPS) if taken is not None else 0
        while first < n_ticks:
            last = min(n_ticks, _next(first, PROGRESS_EVERY), _next(first, TAP_BLOCK_STEPS) if taken else n_ticks)
            # where a period starts, as the scheme does: a full block, or what a slow loop holds
            if taken is not None and taken.requests >= handover_at:
                handover_at = taken.handed_over(time.perf_counter_ns(), TAP_BLOCK_STEPS)
            if registers is not None:
                try:
                    block, released, failed = registers.steps(first, last - first)
                except KeyboardInterrupt:  # it arrived during the block's C call: its steps are handed over
                    self._hand_over(first, *registers.completed(first), time.perf_counter_ns(), readers,
                                    residual_power, residual_energy, release_times, taken)
                    raise
                if failed is not None:
                    self._stopped(Stopped(self.natives[failed.native], registers.failure(failed)), first, block,
                                  released, readers, residual_power, residual_energy, release_times, taken)
                last = first + len(block)  # all of them, or those within the program's time budget
                newest = [registers.get(t.outputs) for t in self.texts]
            else:
                rows, times = [], []
                try:
                    state, newest, energies, inputs_at_end = self.steps(first, last, state, newest, energies,
                                                                        rows.extend, times.append,
                                                                        time.perf_counter_ns)
                except Stopped as stopped:
                    self._stopped(stopped, first, *self._block(rows, times), readers, residual_power,
                                  residual_energy, release_times, taken)
                block, released = self._block(rows, times)
            self._hand_over(first, block, released, time.perf_counter_ns(), readers, residual_power, residual_energy,
                            release_times, taken)
            for reader, values in zip(readers, newest):
                reader.newest = values
            first = last
            if progress is not None and last % PROGRESS_EVERY == 0:
                progress(last)
        if registers is not None:
            state = [registers.get(t.state) for t in self.texts]
            inputs_at_end = [registers.get(t.inputs_at_end) for t in self.texts]
        if n_ticks:  # the subsystems take the state the last step left (a run of no step leaves them where they are)
            for s, z, w in zip(plan.subsystems, state, inputs_at_end):
                self.direct.took_steps(s, n_ticks, z, w)
        return n_ticks

    def _block(self, rows: list[float], times: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The Python loop's rows (whole steps) as an array, a row per step, and the steps' release times (``times``
        may hold one more: the step that raised)."""
        block = float64s(rows).reshape(len(rows) // self.row_width, self.row_width)
        return block, int64s(times)[:len(block)]

    def _hand_over(self, first: int, block: np.ndarray, released: np.ndarray, done_ns: int,
                   readers: list[OutputReader], residual_power: RowWindow, residual_energy: RowWindow,
                   release_times: RowWindow, taken: TakenRows | None) -> int:
        """The steps from ``first`` whose rows ``block`` holds (a row per step) to the run's windows and the tap;
        ``released``: their release times, ``done_ns``: when the last completed. Returns how many."""
        n_bonds = len(self.plan.bonds)
        count = len(block)
        for reader, values in zip(readers, _columns(block, self.output_ends, self.width)):
            reader.window.put_rows(first + 1, values)
        residual_power.put_rows(first + 1, block[:, self.bonds_start:self.bonds_start + n_bonds])
        residual_energy.put_rows(first + 1, block[:, self.bonds_start + n_bonds:])
        release_times.put_rows(first, released)
        if taken is not None:  # a step completed where the next was released (the loop's next statement)
            completed = np.empty(count, dtype=np.int64)
            completed[:-1], completed[-1:] = released[1:count], done_ns
            taken.append_rows(block, released, completed)
        return count

    def _stopped(self, stopped: Stopped, first: int, block: np.ndarray, released: np.ndarray,
                 readers: list[OutputReader], residual_power: RowWindow, residual_energy: RowWindow,
                 release_times: RowWindow, taken: TakenRows | None) -> None:
        """Hand over the steps before the one that raised (``block``, ``released``: as ``_hand_over`` takes them)
        and raise what the scheme's loop raises: as it, the tap gets that step's request (its commands, the outputs
        at its start), not its replies."""
        count = self._hand_over(first, block, released, time.perf_counter_ns(), readers, residual_power,
                                residual_energy, release_times, taken)
        if taken is not None:
            taken.unanswered()
        if stopped.subsystem is None:
            raise stopped.error
        raise self.direct.failure(self.plan.subsystems[stopped.subsystem], first + count + 1, stopped.error) from None


class Stopped(BaseException):  # not an error of its own: it carries one out of the generated loop
    """A step of the generated loop raised ``error`` in the statements of ``subsystem`` (its plan index; None: outside
    them, an interrupt). The step is the first the loop did not extend its row for."""

    def __init__(self, subsystem: int | None, error: BaseException) -> None:
        super().__init__(subsystem, error)
        self.subsystem, self.error = subsystem, error


def _columns(block: np.ndarray, ends: np.ndarray, widths: list[int]) -> list[np.ndarray]:
    """The columns of ``block`` that end at each of ``ends``, ``widths`` of them each."""
    return [block[:, end - width:end] for end, width in zip(ends, widths)]


def _next(tick: int, every: int) -> int:
    """The first multiple of ``every`` after ``tick``."""
    return (tick // every + 1) * every


def compiled_steps(plan: Plan, direct: SubsystemCalls, tapped: bool = False) -> CompiledSteps | None:
    """The scene's macro-steps as one loop, or None where the generic loop must run them (see the module text; the
    caller has ruled out correctors, pacing and a tap that takes messages one by one); ``tapped``: a tap takes its
    rows (``TakenRows``: Jacobi only, whose commands are the outputs of the step before)."""
    subs = plan.subsystems
    if (plan.sequential and tapped) or any(s.ratio != 1 or s.zero_order_sources is None for s in subs):
        return None
    texts = [direct.step_text(s, f"s{s.index}_", f"tick * {plan.base_step_ns}") for s in subs]
    if any(text is None or len(text.outputs) != len(s.outputs) for text, s in zip(texts, subs)):
        return None
    return CompiledSteps(plan, direct, texts)


def _loop_text(plan: Plan, texts: list[StepText], statements: list[str], row: list[str]) -> str:
    """The source of ``steps(first, last, state, newest, energies, extend, stamp, perf)``: macro-steps ``first`` …
    ``last - 1`` (each one ``statements``, :func:`_step_statements`) from each subsystem's ``state`` and ``newest``
    outputs and each bond's energy, each step's ``row`` (:func:`_row`) extended; it returns the state, the newest
    outputs, the energies and the input values at the last step's end."""
    head = ["def steps(first, last, state, newest, energies, extend, stamp, perf):"]
    for s, text in zip(plan.subsystems, texts):
        if text.state:
            head.append(f"    {unpacked(text.state)} = state[{s.index}]")
        if text.outputs:
            head.append(f"    {unpacked(text.outputs)} = newest[{s.index}]")
    energies = _energies(plan)
    if energies:
        head.append(f"    {unpacked(energies)} = energies")
    body = statements + [f"extend(({', '.join(row)},))"]
    lines = head + ["    stepping = None", "    try:", "        for tick in range(first, last):"]
    lines += [f"            {line}" for line in body]
    lines += ["    except BaseException as error:", "        raise Stopped(stepping, error) from None"]
    lines.append(f"    return [{', '.join(f'[{_listed(t.state)}]' for t in texts)}], "
                 f"[{', '.join(f'[{_listed(t.outputs)}]' for t in texts)}], [{_listed(energies)}], "
                 f"[{', '.join(f'[{_listed(t.inputs_at_end)}]' for t in texts)}]")
    return "\n".join(lines)


def _step_statements(plan: Plan, texts: list[StepText], natives: list[int] = ()) -> list[str]:
    """One macro-step: its release time stamped, stage after stage (Jacobi: one) the commands from the newest
    outputs and the subsystems' steps, then every bond's δP and δE; the step of ``natives[k]`` as ``native(k)``
    (``register_loop``)."""
    subs = plan.subsystems
    body = [STAMP_STATEMENT]
    for stage in plan.stages:  # stage after stage (Jacobi: one), its commands from the newest outputs, then its steps
        for i in stage:
            body.extend(f"{c} = {texts[source].outputs[output]}"
                        for c, (source, output) in zip(texts[i].coefficients, subs[i].zero_order_sources))
        for i in stage:
            body.append(f"stepping = {i}")
            body.extend([f"{NATIVE_CALL}({natives.index(i)})"] if i in natives else texts[i].statements)
            body.extend(f"{z} = {n}" for z, n in zip(texts[i].state, texts[i].new_state))
    body.append("stepping = None")
    step_s = plan.base_step_ns * 1e-9
    for b, bond in enumerate(plan.bonds):
        force_side, motion_side = texts[bond.force_side], texts[bond.motion_side]
        power = "0.0"  # as the scheme adds the components up, from 0.0
        for force, velocity_input, force_input, velocity in bond.components:
            term = residual_power_text(force_side.outputs[force], force_side.coefficients[velocity_input],
                                       motion_side.coefficients[force_input], motion_side.outputs[velocity])
            power = f"{power} + ({term})"
        body.append(f"b{b}_power = {power}")
        body.append(f"b{b}_energy = b{b}_energy + b{b}_power * {step_s!r}")
    return body


def _energies(plan: Plan) -> list[str]:
    return [f"b{b}_energy" for b in range(len(plan.bonds))]


def _row(plan: Plan, texts: list[StepText]) -> list[str]:
    """A step's row: every subsystem's outputs, the bonds' δP, their δE."""
    return [name for text in texts for name in text.outputs] + [f"b{b}_power" for b in range(len(plan.bonds))] \
        + _energies(plan)


def _listed(names) -> str:
    return ", ".join(names)
