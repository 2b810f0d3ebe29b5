"""The run plan: who feeds whom, in which order subsystems initialise, and which bonds are monitored.

Compiled once from a scene and the ports of its subsystems; the run loop then only does index
arithmetic. Indices refer to ``Plan.subsystems`` and to each subsystem's port order.
"""
from __future__ import annotations

from dataclasses import dataclass

from zencosim.manager.scene.load import Scene, SceneError
from zencosim.subsystems.params import Problems
from zencosim.subsystems.ports import Port


@dataclass(frozen=True)
class Feed:
    """Outputs ``outputs`` of subsystem ``source`` feed inputs ``inputs`` of one target, in that order."""

    source: int
    outputs: tuple[int, ...]
    inputs: tuple[int, ...]


@dataclass(frozen=True)
class SubsystemPlan:
    index: int
    name: str
    ratio: int  # communication step / base macro step
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]  # coupling outputs, then the energy monitor
    feeds: tuple[Feed, ...]
    effects: tuple[str, ...]  # active effects, as built
    order: int  # Lagrange order of the input polynomials this subsystem receives (0 ZOH, 1 FOH, 2 SOH)

    @property
    def energy_output(self) -> int | None:
        """Index of the energy output, the last one (None: the model reports no energy, e.g. an FMU without)."""
        return len(self.outputs) - 1 if self.outputs and self.outputs[-1].quantity == "energy" else None


@dataclass(frozen=True)
class BondPlan:
    """Indices of the four signals of a power bond (see manager.scheme.residual), one per component."""

    name: str
    force_side: int
    force_output: tuple[int, ...]
    velocity_input: tuple[int, ...]
    motion_side: int
    velocity_output: tuple[int, ...]
    force_input: tuple[int, ...]

    @property
    def components(self) -> tuple[tuple[int, int, int, int], ...]:
        """(force output, velocity input, force input, velocity output) of each component."""
        return tuple(zip(self.force_output, self.velocity_input, self.force_input, self.velocity_output))


@dataclass(frozen=True)
class Plan:
    subsystems: tuple[SubsystemPlan, ...]
    bonds: tuple[BondPlan, ...]
    init_rounds: tuple[tuple[int, ...], ...]  # who reports initial outputs first (no feedthrough), then who
    signals: dict[str, tuple[int, int]]  # coupling signal name -> (subsystem, output)
    base_step_ns: int
    n_ticks: int

    def by_name(self, name: str) -> SubsystemPlan:
        return next(s for s in self.subsystems if s.name == name)


def compile_plan(scene: Scene, ports: dict[str, tuple[tuple[Port, ...], tuple[Port, ...], tuple[str, ...]]]) -> Plan:
    """Build the plan; ``ports[name] = (inputs, outputs, effects)`` of each built subsystem.

    Raises :class:`SceneError` when an input is unfed, a route joins ports of different units, or
    outputs with direct feedthrough form an algebraic loop that an explicit scheme cannot initialise.
    Inputs that a coupling's ``computed_inputs()`` lists (coupling variables of a rigid joint) are fed
    by the manager.
    """
    names = list(scene.subsystems)
    index = {name: i for i, name in enumerate(names)}
    problems = Problems()
    routes = [r for c in scene.couplings.values() for r in c.routes()]
    port_index = {n: ({p.name: j for j, p in enumerate(ports[n][0])}, {p.name: j for j, p in enumerate(ports[n][1])})
                  for n in names}

    fed: dict[str, dict[int, tuple[int, int]]] = {n: {} for n in names}
    computed = {(sub, port_index[sub][0][port]) for c in scene.couplings.values()
                for sub, port in getattr(c, "computed_inputs", tuple)()}
    for route in routes:
        source_port = ports[route.source][1][port_index[route.source][1][route.output]]
        target_in = port_index[route.target][0][route.input]
        target_port = ports[route.target][0][target_in]
        if source_port.unit != target_port.unit:
            problems.add("couplings", f"{route.source}.{route.output} [{source_port.unit}] feeds "
                         f"{route.target}.{route.input} [{target_port.unit}]: units differ")
        fed[route.target][target_in] = (index[route.source], port_index[route.source][1][route.output])

    plans = []
    for i, name in enumerate(names):
        inputs, outputs, effects = ports[name]
        for j, port in enumerate(inputs):
            if j not in fed[name] and (name, j) not in computed:
                problems.add(f"subsystems.{name}", f"input {port.name} is fed by no coupling")
        groups: dict[int, list[tuple[int, int]]] = {}
        for j, (source, output) in sorted(fed[name].items()):
            groups.setdefault(source, []).append((output, j))
        feeds = tuple(Feed(src, tuple(o for o, _ in pairs), tuple(j for _, j in pairs)) for src, pairs in groups.items())
        settings = scene.subsystems[name].settings
        order = scene.manager.extrapolation if settings.extrapolation is None else settings.extrapolation
        plans.append(SubsystemPlan(i, name, settings.comm_ratio, inputs, outputs, feeds, effects, order))

    bonds = []
    for coupling in scene.couplings.values():
        for b in coupling.bonds():
            f_in, f_out = port_index[b.force_side]
            m_in, m_out = port_index[b.motion_side]
            bonds.append(BondPlan(b.name, index[b.force_side], tuple(f_out[n] for n in b.force),
                                  tuple(f_in[n] for n in b.velocity_input), index[b.motion_side],
                                  tuple(m_out[n] for n in b.velocity), tuple(m_in[n] for n in b.force_input)))

    init_rounds = _init_rounds(plans, problems)
    if problems:
        raise SceneError(scene.path, problems)
    signals = {p.name: (s.index, j) for s in plans for j, p in enumerate(s.outputs) if p.quantity != "energy"}
    return Plan(tuple(plans), tuple(bonds), init_rounds, signals, scene.manager.macro_step_ns,
                scene.manager.duration_ns // scene.manager.macro_step_ns)


def _init_rounds(plans: list[SubsystemPlan], problems: Problems) -> tuple[tuple[int, ...], ...]:
    """Order the initial-output requests: a subsystem with a feedthrough output waits for its sources."""
    waits = {s.index: ({f.source for f in s.feeds} if any(p.feedthrough for p in s.outputs) else set()) for s in plans}
    done: set[int] = set()
    rounds = []
    while len(done) < len(plans):
        ready = tuple(sorted(i for i, deps in waits.items() if i not in done and deps <= done))
        if not ready:
            loop = ", ".join(plans[i].name for i in sorted(set(waits) - done))
            problems.add("couplings", f"outputs with direct feedthrough form an algebraic loop between {loop}; "
                         "an explicit scheme cannot initialise them")
            break
        rounds.append(ready)
        done.update(ready)
    return tuple(rounds)
