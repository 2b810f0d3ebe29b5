"""The manager's replica over Zenoh takes a run's replies a block of macro-steps at a time (issue 26).

Over Zenoh the manager follows the run with a replica of the scheme that executes no command: it computes every
command, checks that each reply answers it (the CRC-32 in the reply's header), commits the outputs and evaluates
every bond's residual power and energy (paper 002 Eqs. 8–9, 13). The replies reach it in batches
(``subsystems.process.host``). When the run is single-rate Jacobi, every subsystem takes zero-order inputs each fed
once (``SubsystemPlan.zero_order_sources``) and nothing but the record is asked of the follower (no corrector, no
status, no tap: an unrecorded run), one macro-step j of it is: each subsystem's STEP command is the header and its
sources' output bytes of step j as they arrived (paper 000 §2.1, ZOH), and each reply for step j + 1 must be the
OUTPUT answering it. The scheme (``manager.scheme.jacobi``) then yields :class:`Follow` requests and is sent whole
macro-steps of replies at once — ``{subsystem: [replies for steps j + 1 … j + m]}`` — which
:class:`FollowedBlocks` checks and commits with numpy, all of a block or none of it: the headers (each an OUTPUT for
its step, as ``check_output``'s first test), the references against the CRC-32s of the commands built for the block,
the outputs copied into the trajectories as they arrived, the residual power of each bond from the same operations
in the same order as ``bond_residual_power`` (so bit for bit), its energy added up step after step
(``np.cumsum`` adds in order), the steps' release times and progress. A block with anything else in it — a reply
that must be dropped, an ERROR, a wrong reference — is not taken: the scheme goes on from its first step with its
generic exchanges, which screen, drop and name the failure as before, and the replica queues the block again.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scheme.base import PROGRESS_EVERY, OutputReader
from zencosim.manager.scheme.window import RowWindow
from zencosim.manager.wire.protocol import VERSION, Kind, command_refs, encode_rows, message_dtype


@dataclass(frozen=True)
class Follow:
    """The request of a follower for whole macro-steps from base step ``tick`` on (up to ``end``): the replies of
    every subsystem for steps ``tick + 1 …``, the same number of each (see the module text)."""

    tick: int
    end: int


class FollowedBlocks:
    """Checks and commits blocks of whole macro-steps for a follower replica's scheme (see the module text)."""

    def __init__(self, plan: Plan, readers: list[OutputReader], residual_power: RowWindow,
                 residual_energy: RowWindow, energies: list[float], bond_ticks: list[int], release_times: RowWindow,
                 progress: Callable[[int], None] | None) -> None:
        self.plan, self.readers = plan, readers
        self.residual_power, self.residual_energy = residual_power, residual_energy
        self.energies, self.bond_ticks = energies, bond_ticks  # the scheme's: each bond's newest δE and its step
        self.release_times, self.progress = release_times, progress
        subs = plan.subsystems
        self.names = [s.name for s in subs]
        self.outputs = [message_dtype(len(s.outputs)) for s in subs]  # each subsystem's OUTPUT
        self.sources = [s.zero_order_sources for s in subs]
        self.step_s = plan.base_step_ns * 1e-9

    def take(self, block: dict[str, list[bytes]], tick: int) -> bool:
        """Commit the replies of ``block`` for steps ``tick + 1 …`` when every one is the OUTPUT answering the command
        this replica computes for it (True); else nothing (False)."""
        plan, readers = self.plan, self.readers
        count = len(block[self.names[0]])
        steps = np.arange(tick + 1, tick + count + 1)
        replies = []
        for s, name in enumerate(self.names):
            size = self.outputs[s].itemsize
            if any(len(reply) != size for reply in block[name]):  # each of its size, and (below) an OUTPUT
                return False
            reply = np.frombuffer(b"".join(block[name]), self.outputs[s])
            header = reply["header"]  # of its count for its step: check_output's first test
            if not ((header["version"] == VERSION) & (header["kind"] == Kind.OUTPUT)
                    & (header["count"] == len(plan.subsystems[s].outputs)) & (header["step"] == steps)).all():
                return False
            replies.append(reply)
        # each subsystem's outputs at steps tick … tick + count: the newest committed, then the block's
        values = [np.concatenate((np.asarray(reader.newest, float)[None], reply["values"]))
                  for reader, reply in zip(readers, replies)]
        inputs = []
        for s, sub in enumerate(plan.subsystems):  # its commands (ZOH: its sources' outputs at each step's start)
            held = np.empty((count, len(sub.inputs)))
            for i, (source, output) in enumerate(self.sources[s]):
                held[:, i] = values[source][:-1, output]
            commands = encode_rows(Kind.STEP, steps - 1, plan.base_step_ns, held, 1, 0)
            if not np.array_equal(command_refs(commands), replies[s]["header"]["ref"]):
                return False
            inputs.append(held)
        for reader, reply, name in zip(readers, replies, self.names):
            reader.window.put_rows(tick + 1, reply["values"])
            reader.newest = tuple(reply["values"][-1].tolist())
            reader.newest_bytes = block[name][-1]
        self._bonds(values, inputs, tick, count)
        self.release_times.put_rows(tick, np.full(count, time.perf_counter_ns(), np.int64))
        if self.progress is not None:
            for done in range((tick // PROGRESS_EVERY + 1) * PROGRESS_EVERY, tick + count + 1, PROGRESS_EVERY):
                self.progress(done)
        return True

    def _bonds(self, values: list[np.ndarray], inputs: list[np.ndarray], tick: int, count: int) -> None:
        """Every bond's δP at steps ``tick + 1 …`` (``bond_residual_power``: from 0.0, component after component) and
        δE (the energy before plus δP × 1 step × the step [s], step after step)."""
        powers = np.zeros((count, len(self.plan.bonds)))
        energies = np.zeros_like(powers)
        for b, bond in enumerate(self.plan.bonds):
            force_side, motion_side = values[bond.force_side][1:], values[bond.motion_side][1:]
            power = np.zeros(count)
            for force, velocity_input, force_input, velocity in bond.components:
                power = power + (inputs[bond.motion_side][:, force_input] * motion_side[:, velocity]
                                 - force_side[:, force] * inputs[bond.force_side][:, velocity_input])
            powers[:, b] = power
            energies[:, b] = np.cumsum(np.concatenate(([self.energies[b]], power * 1 * self.step_s)))[1:]
            self.energies[b], self.bond_ticks[b] = float(energies[-1, b]), tick + count
        self.residual_power.put_rows(tick + 1, powers)
        self.residual_energy.put_rows(tick + 1, energies)
