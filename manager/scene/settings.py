"""The settings tables of a scene: ``[manager]`` with its sub-tables, ``[outputs]`` and the generic keys of
``[subsystems.<name>]``. Each field carries its unit and bounds (``subsystems.params.quantity``);
``subsystems.params.read_table`` reads and checks a table into one of these classes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from zencosim.compensation.implicit.coupling_laws import Baumgarte, CouplingMethod, Projection, WeightedMultiplier
from zencosim.subsystems.integrators import INTEGRATORS
from zencosim.subsystems.integrators.own_solver import OwnSolver
from zencosim.subsystems.models import ModelTraits, model_class, model_traits
from zencosim.manager.scene.times import nanoseconds
from zencosim.subsystems.params import quantity


@dataclass(frozen=True)
class CorrectionSettings:
    """The ``[manager.correction]`` table: energy correction (paper 002 Eqs. 13–17, see manager.correction).

    No table, or ``enabled = false``: no corrector is built.
    """

    enabled: bool = True
    mu: float | Literal["auto"] = field(default="auto", metadata=quantity("", minimum=0.0, maximum=1.0))  # μ, Eq. 13
    nu: float = field(default=0.0, metadata=quantity("", minimum=0.0, maximum=1.0))  # ν, weight of 𝒰 in Eq. 17
    cap_fraction: float | None = field(default=1.0, metadata=quantity("", minimum=0.0))  # |f_corr| <= cap_fraction |f|
    cap_force: float | None = field(default=None, metadata=quantity("N", minimum=0.0))  # |f_corr| <= cap_force [N]


@dataclass(frozen=True)
class SpikeSettings:
    """The ``[manager.spikes]`` table: the residual-power spike detector (see manager.results.monitor)."""

    window: float = field(default=2.0, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # trailing window [s]
    threshold: float = field(default=50.0, metadata=quantity("", minimum=0.0, exclusive_minimum=True))  # x baseline
    merge_gap: float = field(default=0.1, metadata=quantity("s", minimum=0.0))  # flagged points closer than this join [s]


@dataclass(frozen=True)
class ImplicitSettings:
    """The ``[manager.implicit]`` table: the coupling method of paper 003 and its corrector iteration.

    The degree k of the predictor and corrector polynomials is ``manager.extrapolation``. Parameters of
    the methods not chosen are not used.
    """

    method: Literal["baumgarte", "weighted-multiplier", "projection"] = "baumgarte"
    mu: float = field(default=5e-3, metadata=quantity("s", minimum=0.0))  # Baumgarte: beta = 2 mu [s], gamma = mu^2 [s^2] (§3.7.1)
    index: int = field(default=1, metadata=quantity("", minimum=1, maximum=3))  # Baumgarte: 1, 2 (gamma = 0), 3 (beta = gamma = 0)
    a: float = field(default=1.0, metadata=quantity("", minimum=0.0))  # weighted multiplier: weight of the velocity level
    b: float = field(default=1.0, metadata=quantity("", minimum=0.0))  # weighted multiplier: weight of the acceleration level
    max_iterations: int = field(default=1, metadata=quantity("", minimum=1))  # corrector runs per macro-step
    tolerance: float = field(default=1e-8, metadata=quantity("", minimum=0.0))  # relative change of e ending the iteration
    sensitivity_step: float = field(default=1e-4, metadata=quantity("", minimum=0.0, exclusive_minimum=True))  # relative perturbation of e
    divergence_gap: float = field(default=1.0, metadata=quantity("m", minimum=0.0, exclusive_minimum=True))  # the run stops when the joint opens wider

    def coupling_method(self) -> CouplingMethod:
        """The method with its parameters in SI units (Baumgarte's beta [s] and gamma [s^2])."""
        if self.method == "baumgarte":
            return Baumgarte.from_mu(self.mu, self.index)
        if self.method == "weighted-multiplier":
            return WeightedMultiplier(self.a, self.b)
        return Projection()


# the most p_gain + i_gain: a sum of 1/k is the deadbeat gain for an error of order k in the step (k >= 1), more
# over-corrects (libcosimpy's sum is 0.35); the law raises the error ε, the root of a positive float and so at least
# 2.2e-162, to minus the sum: at most 4.5e161 at 1, which stays finite
MOST_GAIN = 1.0


@dataclass(frozen=True)
class EnergyControlSettings:
    """The ``[manager.energy_control]`` table, with ``manager.step_control = "energy"``: the macro-step adapted
    from the bonds' residual energy by a PI law — libcosim's ``ecco_algorithm`` (Sadjina & Pedersen 2020, the
    ECCO method), its parameters under its names (``manager.scheme.energy_step`` gives the law).

    Every macro-step is a whole multiple of ``manager.macro_step`` (the subsystems' micro-steps divide it), so
    are ``step_size`` (the first step), ``min_step_size`` and ``max_step_size``. Defaults: the step sizes and
    ``abs_tolerance`` from the scene (None: ``manager.scheme.energy_step.step_bounds`` and ``abs_tolerance``: the
    macro-step as the first and smallest step, some tens of it as the largest, a tolerance relative to the energy at
    t_0), the rest libcosimpy's ``EccoParams`` where they make a working controller, its README's change rates
    (libcosimpy's 0.01 … 0.2 would only ever shrink the step).

    The law's other parameters are bounded (docs/step-control.md gives the reasons): a safety factor of 0.1 to 1
    (a fraction of the step the tolerance allows), change rates of 1e-3 to 1e3 (a step changes at most a
    thousandfold per step), an absolute tolerance above 0 (the law divides by the tolerance, which is the absolute
    one alone when every residual is 0), a relative one of 0 to 1, and PI gains of at least 0 summing to more than
    0 (else the step ignores the error) and at most ``MOST_GAIN`` (the deadbeat gain of an error of the first
    order; the law raises the error to minus their sum, which stays finite).
    """

    max_step_size: float | None = field(default=None, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # [s]; None: 20 min_step_size
    step_size: float | None = field(default=None, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # the first [s]; None: min_step_size
    min_step_size: float | None = field(default=None, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # [s]; None: manager.macro_step
    safety_factor: float = field(default=0.8, metadata=quantity("", minimum=0.1, maximum=1.0))
    min_change_rate: float = field(default=0.2, metadata=quantity("", minimum=1e-3, maximum=1e3))  # per step
    max_change_rate: float = field(default=1.5, metadata=quantity("", minimum=1e-3, maximum=1e3))
    # residual energy per step [J]; None: 1e-3 of the energy at t_0
    abs_tolerance: float | None = field(default=None, metadata=quantity("J", minimum=0.0, exclusive_minimum=True))
    rel_tolerance: float = field(default=1e-4, metadata=quantity("", minimum=0.0, maximum=1.0))
    p_gain: float = field(default=0.2, metadata=quantity("", minimum=0.0, maximum=MOST_GAIN))
    i_gain: float = field(default=0.15, metadata=quantity("", minimum=0.0, maximum=MOST_GAIN))

    def problems(self) -> list[tuple[str, str]]:
        gains = self.p_gain + self.i_gain
        if not 0.0 < gains <= MOST_GAIN:
            return [("p_gain", f"expected 0 < p_gain + i_gain <= {MOST_GAIN} (no gain: the step ignores the error), "
                               f"got {self.p_gain!r} + {self.i_gain!r}")]
        return []


@dataclass(frozen=True)
class ManagerSettings:
    """The ``[manager]`` table: how the run is orchestrated."""

    duration: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # simulated time [s]
    macro_step: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # base communication step [s]
    scheme: Literal["jacobi", "gauss-seidel", "implicit"] = "jacobi"
    # gauss-seidel: the subsystems in the order they step within a macro-step (() : the plan's, run_plan.stages)
    order: tuple[str, ...] = ()
    extrapolation: int = field(default=0, metadata=quantity("", minimum=0, maximum=2))  # Lagrange order (implicit: k)
    timeout: float = field(default=10.0, metadata=quantity("s", minimum=0.0, exclusive_minimum=True))
    realtime: bool = False
    # real-time levers (docs/realtime.md): SCHED_FIFO priority of the thread that paces the steps (0: normal
    # scheduling), and each subsystem process's pacing thread kept to one CPU (its index modulo the CPUs)
    realtime_priority: int = field(default=0, metadata=quantity("", minimum=0, maximum=99))
    realtime_affinity: bool = False
    record: str = ""  # write an MCAP recording of every run to this path ("" = none; also: zencosim run --record)
    zenoh_config: str = ""  # a Zenoh JSON5 configuration file for a run over Zenoh ("" = none; also: --zenoh-config)
    correction: CorrectionSettings | None = None  # [manager.correction]
    spikes: SpikeSettings = SpikeSettings()  # [manager.spikes]
    compensation: Literal["none", "eigenstructure"] = "none"  # paper 000 compensator (docs/compensation.md)
    implicit: ImplicitSettings | None = None  # [manager.implicit], with scheme = "implicit"
    # "energy": the macro-step adapts to the bonds' residual energy ([manager.energy_control]); "fixed": macro_step
    step_control: Literal["fixed", "energy"] = "fixed"
    energy_control: EnergyControlSettings | None = None  # [manager.energy_control], with step_control = "energy"

    @property
    def corrects(self) -> bool:
        """True when the scene asks for energy correction."""
        return self.correction is not None and self.correction.enabled

    @property
    def macro_step_ns(self) -> int:
        return nanoseconds(self.macro_step, whole=False)  # whole and in range when loaded (manager.scene.checks)

    @property
    def duration_ns(self) -> int:
        return nanoseconds(self.duration, whole=False)  # whole and in range when loaded (manager.scene.checks)


@dataclass(frozen=True)
class OutputSettings:
    """The ``[outputs]`` table: which signals the summary reports and against which reference."""

    signals: tuple[str, ...] = ()
    reference: Literal["analytic", "solve_ivp", "extrapolated", "none"] = "analytic"  # extrapolated: a study's


@dataclass(frozen=True)
class SubsystemSettings:
    """The generic keys of a ``[subsystems.<name>]`` table; the rest belongs to its model."""

    model: str  # a built-in model, "fmu", "package.module:Class" or a registered name (subsystems.models)
    micro_step: float = field(metadata=quantity("s", minimum=0.0, exclusive_minimum=True))  # [s]
    integrator: str | None = None  # None: the model's default (symplectic_euler; a co-simulation FMU: own)
    comm_ratio: int = field(default=1, metadata=quantity("", minimum=1))  # communication step / macro step
    extrapolation: int | None = field(default=None, metadata=quantity("", minimum=0, maximum=2))  # of its inputs

    def problems(self) -> list[tuple[str, str]]:
        found = []
        if self.integrator is not None and self.integrator not in INTEGRATORS:
            found.append(("integrator", f"expected one of {', '.join(sorted(INTEGRATORS))}, got {self.integrator!r}"))
        return found

    def integrator_problem(self, traits: ModelTraits) -> str | None:
        """Why this subsystem's integrator cannot advance its model (None: it can)."""
        integrator = INTEGRATORS[self.integrator]
        if traits.advances_itself != (integrator is OwnSolver):
            return (f"model {self.model} advances itself: expected integrator '{OwnSolver.name}' or none" if traits.advances_itself
                    else f"'{OwnSolver.name}' is for a model that advances itself (a co-simulation FMU)")
        if integrator.second_order_only and not traits.second_order:
            usable = sorted(n for n, i in INTEGRATORS.items() if not i.second_order_only and i is not OwnSolver)
            return (f"{self.integrator} needs a state of positions and velocities; model {self.model} is first order: "
                    f"expected one of {', '.join(usable)}")
        return None

    @property
    def micro_step_ns(self) -> int:
        return nanoseconds(self.micro_step, whole=False)  # whole and in range when loaded (manager.scene.checks)


@dataclass(frozen=True)
class SubsystemScene:
    """One subsystem of a scene: its generic settings and its model's own description."""

    name: str
    settings: SubsystemSettings
    spec: Any  # what the model's ``read`` returned

    @property
    def traits(self) -> ModelTraits:
        """What its model can do (``subsystems.models.model_traits``)."""
        return model_traits(model_class(self.settings.model), self.spec)


def extrapolation_order(manager: ManagerSettings, subsystem: SubsystemScene) -> int:
    """The Lagrange order of the inputs ``subsystem`` receives (its own, else the scene's)."""
    own = subsystem.settings.extrapolation
    return manager.extrapolation if own is None else own
