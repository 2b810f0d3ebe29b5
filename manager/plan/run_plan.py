"""The run plan: who feeds whom, in which order subsystems initialise, and which bonds are monitored.

Compiled once from a scene and the ports of its subsystems; the run loop then only does index
arithmetic. Indices refer to ``Plan.subsystems`` and to each subsystem's port order.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from zencosim.manager.plan.memory import memory_problem
from zencosim.manager.scene.load import Scene, SceneError
from zencosim.manager.scene.settings import extrapolation_order
from zencosim.subsystems.params import Problem, Problems
from zencosim.subsystems.ports import Port
from zencosim.subsystems.units import UnitError, exponents


@dataclass(frozen=True)
class Feed:
    """Outputs ``outputs`` of subsystem ``source`` feed inputs ``inputs`` of one target, in that order, as
    polynomials of Lagrange order ``order``."""

    source: int
    outputs: tuple[int, ...]
    inputs: tuple[int, ...]
    order: int


@dataclass(frozen=True)
class InitStep:
    """One initial-output request: subsystem ``subsystem`` gets the values of its ``ready`` inputs (the
    final ones), 0 for the others."""

    subsystem: int
    ready: tuple[int, ...]


@dataclass(frozen=True)
class SubsystemPlan:
    index: int
    name: str
    ratio: int  # communication step / base macro step
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]  # coupling outputs, then the energy monitor
    feeds: tuple[Feed, ...]
    effects: tuple[str, ...]  # active effects, as built
    order: int  # Lagrange order of the input polynomials this subsystem receives (0 ZOH, 1 FOH, 2 SOH): the
    # highest of its feeds' (each the subsystem's, or a signal connection's own, or an Integer's 0)

    @property
    def energy_output(self) -> int | None:
        """Index of the energy output, the last one (None: the model reports no energy, e.g. an FMU without)."""
        return len(self.outputs) - 1 if self.outputs and self.outputs[-1].quantity == "energy" else None

    @property
    def zero_order_sources(self) -> list[tuple[int, int]] | None:
        """With zero-order inputs, every input fed once: the source and output index of each input in input order (a
        ZOH polynomial is the sources' newest sample); None otherwise."""
        if self.order != 0:
            return None
        where = {target: (feed.source, output) for feed in self.feeds
                 for output, target in zip(feed.outputs, feed.inputs)}
        if sorted(where) != list(range(len(self.inputs))):
            return None
        return [where[target] for target in range(len(self.inputs))]


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
    init_rounds: tuple[tuple[InitStep, ...], ...]  # the initial-output requests, round by round (_init_rounds)
    signals: dict[str, tuple[int, int]]  # coupling signal name -> (subsystem, output)
    base_step_ns: int
    n_ticks: int
    # the subsystems that step together, stage after stage, within a macro-step (indices): Jacobi one stage of
    # all, Gauss–Seidel one per subsystem in its order (``stages``)
    stages: tuple[tuple[int, ...], ...] = ()

    def by_name(self, name: str) -> SubsystemPlan:
        return next(s for s in self.subsystems if s.name == name)

    def sources(self, index: int) -> frozenset[int]:
        """The subsystems whose outputs feed subsystem ``index``."""
        return frozenset(f.source for f in self.subsystems[index].feeds)

    def partners(self, index: int) -> frozenset[int]:
        """The subsystems subsystem ``index`` exchanges values with: its sources and the ones it feeds."""
        return self.sources(index) | frozenset(s.index for s in self.subsystems if index in self.sources(s.index))

    @property
    def sequential(self) -> bool:
        """Whether the subsystems step one stage after another (Gauss–Seidel), a stage's replies taken before the
        next stage's inputs are made; else all in one stage (Jacobi)."""
        return len(self.stages) > 1

    @cached_property
    def stage_of(self) -> dict[int, int]:
        """The number of the stage each subsystem steps in."""
        return {i: number for number, stage in enumerate(self.stages) for i in stage}

    def lead(self, source: int, target: int) -> int:
        """Base steps added to a tick before dividing it by ``source``'s ratio, to number ``source``'s newest sample
        when ``target``'s input polynomial is made at that tick: with Jacobi 0 (the sample at or before the tick);
        with Gauss–Seidel, for a source of an earlier stage its ratio (the end of the step it has just taken), and
        of a later stage its ratio − 1 (the end of its step under way, which it took in an earlier macro-step;
        0 single-rate)."""
        stage_of = self.stage_of
        if not self.sequential or stage_of[source] == stage_of[target]:
            return 0
        ratio = self.subsystems[source].ratio
        return ratio if stage_of[source] < stage_of[target] else ratio - 1

    def tracked(self, local: frozenset[int]) -> frozenset[int]:
        """What a replica computing the commands of ``local`` subsystems follows: them and their sources."""
        return frozenset(local).union(*(self.sources(i) for i in local))


def same_unit(a: str, b: str) -> bool:
    """Whether two SI unit strings name one unit (``Pa`` and ``N/m2``; unit strings zencosim cannot read must
    be equal)."""
    if a == b:
        return True
    try:
        return exponents(a) == exponents(b)
    except UnitError:
        return False


def compile_plan(scene: Scene, ports: dict[str, tuple[tuple[Port, ...], tuple[Port, ...], tuple[str, ...]]]) -> Plan:
    """Build the plan; ``ports[name] = (inputs, outputs, effects)`` of each built subsystem.

    Raises :class:`SceneError` when an input is unfed, a route joins ports of different units, or
    outputs with declared direct feedthrough form an algebraic loop that an explicit scheme cannot initialise
    (feedthrough is per output: a chain whose force sides feed through from states is no loop; a loop through an
    output whose component does not declare its dependencies is initialised as libcosim does, ``_init_rounds``).
    Inputs that a coupling's ``computed_inputs()`` lists (coupling variables of a rigid joint) are fed
    by the manager.
    """
    names = list(scene.subsystems)
    index = {name: i for i, name in enumerate(names)}
    problems = Problems()
    routes = [r for c in scene.couplings.values() for r in c.routes()]
    port_index = {n: ({p.name: j for j, p in enumerate(ports[n][0])}, {p.name: j for j, p in enumerate(ports[n][1])})
                  for n in names}

    fed: dict[str, dict[int, tuple[int, int, int]]] = {n: {} for n in names}
    computed = {(sub, port_index[sub][0][port]) for c in scene.couplings.values()
                for sub, port in getattr(c, "computed_inputs", tuple)()}
    for route in routes:
        source_port = ports[route.source][1][port_index[route.source][1][route.output]]
        target_in = port_index[route.target][0][route.input]
        target_port = ports[route.target][0][target_in]
        if not same_unit(source_port.unit, target_port.unit):
            problems.add("couplings", f"{route.source}.{route.output} [{source_port.unit}] feeds "
                         f"{route.target}.{route.input} [{target_port.unit}]: units differ")
        if target_port.discrete:  # an Integer or Boolean is held over a step
            order = 0
        elif route.order is not None:
            order = route.order
        else:
            order = extrapolation_order(scene.manager, scene.subsystems[route.target])
        fed[route.target][target_in] = (index[route.source], port_index[route.source][1][route.output], order)

    plans = []
    for i, name in enumerate(names):
        inputs, outputs, effects = ports[name]
        for j, port in enumerate(inputs):
            if j not in fed[name] and (name, j) not in computed:
                problems.add(f"subsystems.{name}", f"input {port.name} is fed by no coupling")
        groups: dict[tuple[int, int], list[tuple[int, int]]] = {}
        for j, (source, output, order) in sorted(fed[name].items()):
            groups.setdefault((source, order), []).append((output, j))
        feeds = tuple(Feed(src, tuple(o for o, _ in pairs), tuple(j for _, j in pairs), order)
                      for (src, order), pairs in groups.items())
        settings = scene.subsystems[name].settings
        order = max((f.order for f in feeds), default=extrapolation_order(scene.manager, scene.subsystems[name]))
        plans.append(SubsystemPlan(i, name, settings.comm_ratio, inputs, outputs, feeds, effects, order))

    bonds = []
    for coupling in scene.couplings.values():
        for b in coupling.bonds():
            f_in, f_out = port_index[b.force_side]
            m_in, m_out = port_index[b.motion_side]
            bonds.append(BondPlan(b.name, index[b.force_side], tuple(f_out[n] for n in b.force),
                                  tuple(f_in[n] for n in b.velocity_input), index[b.motion_side],
                                  tuple(m_out[n] for n in b.velocity), tuple(m_in[n] for n in b.force_input)))

    init_rounds = _init_rounds(plans, problems, {i: _feedthrough_origin(scene, name) for i, name in enumerate(names)})
    if problems:
        raise SceneError(scene.path, problems)
    signals = {p.name: (s.index, j) for s in plans for j, p in enumerate(s.outputs) if p.quantity != "energy"}
    manager = scene.manager
    plan = Plan(tuple(plans), tuple(bonds), init_rounds, signals, manager.macro_step_ns,
                manager.duration_ns // manager.macro_step_ns, stages(scene, plans, init_rounds))
    control = manager.energy_control  # an energy-controlled run: a row per macro-step, at most one per min_step_size
    shortest = manager.macro_step if control is None or control.min_step_size is None else control.min_step_size
    reason = memory_problem(plan, manager.duration_ns // round(shortest * 1e9), manager.duration, shortest)
    if reason:
        raise SceneError(scene.path, [Problem("manager.duration", reason)])
    return plan


def stages(scene: Scene, plans: list[SubsystemPlan], init_rounds: tuple[tuple[InitStep, ...], ...]
           ) -> tuple[tuple[int, ...], ...]:
    """The stages of a macro-step: one of every subsystem (Jacobi, implicit), or one per subsystem (Gauss–Seidel)
    in ``manager.order``, by default in the order their outputs become final at initialisation: a subsystem
    after those whose outputs it passes through directly (a force side after its motion side), ties in scene
    order."""
    if scene.manager.scheme != "gauss-seidel":
        return (tuple(s.index for s in plans),)
    if scene.manager.order:
        index = {s.name: s.index for s in plans}
        return tuple((index[name],) for name in scene.manager.order)
    last_round = {step.subsystem: number for number, round_ in enumerate(init_rounds) for step in round_}
    return tuple((s.index,) for s in sorted(plans, key=lambda s: last_round.get(s.index, 0)))


def _init_rounds(plans: list[SubsystemPlan], problems: Problems, origins: dict[int, str | None]
                 ) -> tuple[tuple[InitStep, ...], ...]:
    """Order the initial-output requests by output: an output is final once every input it depends on at the
    same instant (``Port.direct_inputs``) carries a final value; each round asks every subsystem with outputs
    that can now be finalised, with the inputs that are final (the others 0, which those outputs ignore).
    Outputs without feedthrough are final in the first round. The energy, which feeds nothing, is what the last
    request gives (a subsystem with no other output is asked once, in the first round).

    Outputs left over sit on or behind a loop. A loop through an output whose feedthrough is only FMI's default
    (``Port.undeclared``: an FMU output without ``dependencies``) is initialised as libcosim's fixed-step algorithm
    initialises every system (``fixed_step_algorithm::initialize``): N passes, N the number of subsystems, each
    asking every subsystem with outputs left over, with every input whose source has answered an earlier request
    (the others 0), then one more pass, as libcosim reads the outputs again after ``exitInitializationMode``; the
    last pass's values are the outputs at t_0 and the inputs of the first step. A loop of declared feedthrough is
    refused, named (``origins[i]``: who declares subsystem i's feedthrough, where a scene can state it otherwise).
    """
    sources = {(s.index, j): (f.source, o) for s in plans for f in s.feeds for o, j in zip(f.outputs, f.inputs)}
    depends = {(s.index, k): [sources[(s.index, j)] for j in port.direct_inputs(s.inputs) if (s.index, j) in sources]
               for s in plans for k, port in enumerate(s.outputs)
               if port.quantity != "energy" or len(s.outputs) == 1}
    final: set[tuple[int, int]] = set()
    rounds = []
    while len(final) < len(depends):
        steps, newly = [], set()
        for s in plans:
            finalisable = [(s.index, k) for k in range(len(s.outputs)) if (s.index, k) in depends
                           and (s.index, k) not in final and all(d in final for d in depends[(s.index, k)])]
            if finalisable:
                ready = tuple(j for j in range(len(s.inputs)) if sources.get((s.index, j)) in final)
                steps.append(InitStep(s.index, ready))
                newly.update(finalisable)
        if not steps:
            declared = _declared_loops(plans, depends, final)
            if declared:
                problems.add("couplings", "outputs with direct feedthrough form an algebraic loop: "
                             + _loop_text(plans, declared, origins) + "; an explicit scheme cannot initialise "
                             "them")
                break
            rounds += _passes(plans, depends, final, sources, rounds)
            break
        rounds.append(tuple(steps))
        final |= newly
    return tuple(rounds)


def _declared_loops(plans: list[SubsystemPlan], depends: dict, final: set) -> dict:
    """The outputs left over that sit on or behind a loop of declared feedthrough, each with the ones among them it
    depends on (an undeclared output's dependence is broken by ``_passes``); empty when there is none."""
    left = {node: [d for d in depends[node] if d not in final] for node in depends
            if node not in final and not plans[node[0]].outputs[node[1]].undeclared}
    while True:  # peel off the outputs that depend on none of the others left
        free = [node for node, needs in left.items() if not any(d in left for d in needs)]
        if not free:
            return left
        for node in free:
            del left[node]


def _passes(plans: list[SubsystemPlan], depends: dict, final: set, sources: dict,
            rounds: list[tuple[InitStep, ...]]) -> list[tuple[InitStep, ...]]:
    """libcosim's initialisation of the outputs left over (``_init_rounds``): N + 1 rounds, N the number of
    subsystems, each asking every subsystem with an output left over, with the inputs whose source has answered."""
    pending = sorted({node[0] for node in depends if node not in final})
    answered = {step.subsystem for round_ in rounds for step in round_}
    passes = []
    for _ in range(len(plans) + 1):
        passes.append(tuple(InitStep(i, tuple(j for j in range(len(plans[i].inputs))
                                              if sources.get((i, j), (None,))[0] in answered)) for i in pending))
        answered.update(pending)
    return passes


def _loop_text(plans: list[SubsystemPlan], left: dict, origins: dict[int, str | None]) -> str:
    """One cycle among the outputs ``left`` (each depends on one of the others): ``S1.fc <- S2.x2 <- S1.fc``,
    then who declares the feedthrough of each subsystem on it where ``origins`` says."""
    def name(node: tuple[int, int]) -> str:
        return f"{plans[node[0]].name}.{plans[node[0]].outputs[node[1]].name}"

    node = next(iter(left))
    path: list[tuple[int, int]] = []
    while node not in path:  # every output left depends on one left: walking back must repeat
        path.append(node)
        node = next(d for d in left[node] if d in left)
    cycle = path[path.index(node):] + [node]
    on_it = dict.fromkeys(i for i, _ in cycle)
    said = [f"{plans[i].name}'s {origins[i]}" for i in on_it if origins.get(i)]
    return " <- ".join(name(n) for n in cycle) + (f" (feedthrough: {'; '.join(said)})" if said else "")


def _feedthrough_origin(scene: Scene, name: str) -> str | None:
    """Who declares subsystem ``name``'s feedthrough where a scene can state it otherwise (an external model's
    ``feedthrough`` key), for the message of a loop; None for a built-in model."""
    origin = getattr(scene.subsystems[name].spec, "feedthrough_origin", None)
    return None if origin is None else origin(f"subsystems.{name}")
