"""The real-time probe: a scene paced at a ladder of rates, and the highest rate that keeps a timing budget.

Before hardware is connected, a user needs the rate this machine sustains for this scene: for every rate
of the ladder the scene runs paced (``manager.macro_step`` = 1 / rate, ``manager.duration`` the probe's)
on the chosen bus, and the probe reports the share of missed deadlines and the lateness percentiles
(manager.scheme.pacing: a step released more than 1 % of the macro-step after its deadline missed it).
A rate meets the budget when at most ``missed_share`` of its steps missed and its p99 lateness is at
most ``p99_share_of_step`` of the macro-step; the answer is the highest rate that meets it with every
lower rate of the ladder meeting it too (a machine that fails at 500 Hz and passes at 1 kHz by luck
does not sustain 1 kHz). A subsystem whose micro-step is longer than its communication step at a rate
takes one micro-step per communication step there (the report lists these settings). The numerics change
with the macro-step; the probe measures only time.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass

from zencosim.manager.bus.timing import run_timing
from zencosim.manager.run import execute
from zencosim.manager.scene.load import Scene, SceneError, load_scene

DEFAULT_RATES_HZ = (100.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0)
DEFAULT_DURATION_S = 2.0


@dataclass(frozen=True)
class Budget:
    missed_share: float = 0.01  # at most this share of the steps miss their deadline
    p99_share_of_step: float = 0.3  # p99 lateness at most this share of the macro-step


@dataclass(frozen=True)
class RateResult:
    rate_hz: float
    macro_step_s: float
    steps: int | None = None
    missed_deadlines: int | None = None
    missed_share: float | None = None
    lateness_us_median: float | None = None
    lateness_us_p99: float | None = None
    lateness_us_max: float | None = None
    meets: bool = False
    adjusted: tuple[str, ...] = ()  # overrides the probe added at this rate (a micro-step shortened)
    error: str | None = None  # the scene does not run at this rate (its settings refuse the macro-step)
    skipped: str | None = None  # not run: a lower rate already missed the budget (``probe``'s ``every_rate`` False)


def rate_overrides(scene: Scene, macro_step_s: float) -> tuple[list[str], tuple[str, ...]]:
    """The overrides that run ``scene`` at ``macro_step_s``, and those among them that shorten a micro-step
    longer than its subsystem's communication step to that step."""
    adjusted = tuple(f"subsystems.{name}.micro_step={macro_step_s * s.settings.comm_ratio!r}"
                     for name, s in scene.subsystems.items()
                     if s.settings.micro_step > macro_step_s * s.settings.comm_ratio)
    return [f"manager.macro_step={macro_step_s!r}", *adjusted], adjusted


def probe_rate(source: str, overrides: list[str], bus: str, rate_hz: float, duration_s: float,
               budget: Budget, **bus_options) -> RateResult:
    """The scene paced at ``rate_hz`` for ``duration_s`` on ``bus``."""
    macro_step_s = 1.0 / rate_hz
    try:
        at_rate, adjusted = rate_overrides(load_scene(source, overrides), macro_step_s)
        scene = load_scene(source, [*overrides, *at_rate, f"manager.duration={duration_s!r}"])
    except SceneError as error:
        return RateResult(rate_hz, macro_step_s, error=str(error).splitlines()[-1].strip())
    record, wall_s = execute(scene, bus, realtime=True, **bus_options)
    timing = run_timing(record, wall_s)
    steps = timing["paced_steps"]
    share = timing["missed_deadlines"] / steps
    meets = share <= budget.missed_share and timing["lateness_us_p99"] <= budget.p99_share_of_step * macro_step_s * 1e6
    return RateResult(rate_hz, macro_step_s, steps, timing["missed_deadlines"], share, timing["lateness_us_median"],
                      timing["lateness_us_p99"], timing["lateness_us_max"], meets, adjusted)


def highest_rate(results: list[RateResult]) -> float | None:
    """The highest rate that meets the budget with every lower rate meeting it too (None: not even the lowest)."""
    best = None
    for result in sorted(results, key=lambda r: r.rate_hz):
        if result.skipped is not None:
            break
        if result.error is not None:
            continue
        if not result.meets:
            break
        best = result.rate_hz
    return best


def probe(source: str, overrides: Iterable[str] = (), bus: str = "inproc", rates_hz: Iterable[float] = DEFAULT_RATES_HZ,
          duration_s: float = DEFAULT_DURATION_S, budget: Budget = Budget(),
          done: Callable[[RateResult], None] | None = None, every_rate: bool = False, **bus_options) -> dict:
    """Probe the rates of the ladder, ascending, until one runs and misses the budget: the rates above it are
    reported skipped (no higher rate can be the answer), unless ``every_rate``; ``done`` sees each result as it is
    measured. The report's keys are documented in docs/realtime.md."""
    overrides = list(overrides)
    results: list[RateResult] = []
    missed = None  # the first rate that ran and missed the budget
    for rate_hz in sorted(set(rates_hz)):
        if missed is not None and not every_rate:
            results.append(RateResult(rate_hz, 1.0 / rate_hz, skipped=f"{missed:g} Hz already missed the budget"))
        else:
            results.append(probe_rate(source, overrides, bus, rate_hz, duration_s, budget, **bus_options))
            if missed is None and results[-1].error is None and not results[-1].meets:
                missed = rate_hz
        if done is not None:
            done(results[-1])
    return {"scene": source, "overrides": overrides, "bus": bus, "duration_s": duration_s, "budget": asdict(budget),
            "rates": [asdict(r) for r in results], "highest_rate_hz": highest_rate(results)}
