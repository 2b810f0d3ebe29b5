"""A subsystem that is not a built-in linear model (an FMU, a user's Python model), identified as a discrete-time
linear system at its communication step around the initial operating point.

Over one communication step ``H`` the subsystem maps its internal state ``s_k`` and the coefficients ``c_k`` of its
input polynomial (``w(τ) = Σ_q c_q τ^q``, the extrapolation in force) to ``s_{k+1}`` and to its outputs at the end
of the step; for a linear subsystem::

    s_{k+1} = A s_k + B c_k,    y_{k+1} = C' s_k + D' c_k,

whose Markov parameters ``h_0 = D'``, ``h_j = C' A^{j-1} B`` are the outputs' responses to a pulse of ``c`` in
step 0. They are measured by driving the built subsystem alone (``Subsystem.advance``, so that an FMU receives
its inputs exactly as in a run: the polynomial evaluated at every micro-step) from its initial state, inputs held
at their values at t_0 ``w_0`` (the baseline), and with a pulse of one coefficient in the first step; each probe
restores the state saved at t_0 (``Subsystem.save``), or builds a fresh instance where the component cannot
save its state. Only the inputs a coupling feeds and the outputs another subsystem reads are probed. The
eigensystem realisation algorithm (ERA; Juang & Pappa 1985) realises them: the block Hankel matrix
``H_0 = [h_{i+j+1}]`` of ``r`` block rows and columns has the SVD ``U Σ V^T``; its order ``n`` is the number of
singular values above ``ORDER_TOLERANCE σ_1`` and ``ERROR_MARGIN`` times the probes' own error, and::

    A = Σ_n^{-1/2} U_n^T H_1 V_n Σ_n^{-1/2},   B = Σ_n^{1/2} V_n^T[:, :m],   C' = U_n[:p] Σ_n^{1/2},   D' = h_0

(``H_1 = [h_{i+j+2}]``; the Markov parameters scaled to unit row and column maxima first, so that inputs and
outputs of different units weigh alike). This is ``control.eigensys_realization`` of python-control, in the few
lines of numpy it takes. A slow subsystem's states differ little over a few steps (``σ_n / σ_1`` grows as
``r²``): ``r`` grows from ``HANKEL_ROWS`` until the weakest state stands ``STATE_GAP`` above the next singular
value (the probes' error). A linear probe's pulse grows (up to
``MAX_PULSE_GAIN``) until its responses match their outputs' baseline: a response far below it is exact only to
the baseline's rounding. The realisation enters the exact discrete analysis (``manager.analysis.discrete``)
with the augmented state ``ξ = [s; y]``: ``Φ = [[A, 0], [C', 0]]``, ``Γ_q = [B_q; D'_q]``, ``C_y = [0 I]``,
``D_y = 0`` — the outputs at a communication point are part of the state; ``Φ``'s extra eigenvalues are zero
(redundant states, no pole).

A linear subsystem is identified exactly (to rounding): the pulses are of the inputs' own size
(``δ = max(|w_0|, 1) / H^q``), ``+δ`` and ``−δ/2``, and its responses satisfy ``(y_+ − y_0) + 2 (y_− − y_0) = 0`` to
rounding (``nonlinearity``: its size relative to ``y_+ − y_−``; even and odd nonlinear terms both break it).
Above ``LINEAR_TOLERANCE`` the subsystem is nonlinear: the probes are repeated as central differences at
``LOCAL_AMPLITUDE`` times that size and the result is a local linearisation about the initial operating point
(the free response from the initial state), its order counting singular values above the ``δ²`` error
(``LOCAL_ORDER_TOLERANCE``). Modes that the fed inputs do not excite or the fed outputs do not show are left out
(the minimal realisation): they run free, outside the coupling, and are not the scheme's. What cannot be
identified — a probe that fails at both sizes, responses that are not finite, a realisation whose Markov
parameters miss the measured ones by more than ``FIT_TOLERANCE`` — raises ``IdentificationError``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from zencosim.manager.plan.run_plan import Plan, SubsystemPlan
from zencosim.subsystems.subsystem import Subsystem

HANKEL_ROWS = 16  # r: block rows (and columns) of the Hankel matrix first tried; orders up to r · min(inputs, outputs)
MAX_HANKEL_ROWS = 256  # the most it grows to (522 steps a probe)
STATE_GAP = 1e8  # σ_n / σ_{n+1} at which the weakest state stands clear of the probes' error (its relative error
# ~ σ_{n+1} / σ_n)
VALIDATION_STEPS = 8  # Markov parameters measured beyond the 2r + 1 that ERA uses, to check the fit
ORDER_TOLERANCE = 1e-10  # σ_i / σ_1 above which a singular value is a state (the probes' rounding is ~1e-14) …
ERROR_MARGIN = 100.0  # … and above this many times the probes' own error
LINEAR_TOLERANCE = 1e-9  # |(y_+ − y_0) + 2 (y_− − y_0)| / |y_+ − y_−| below which the subsystem is linear
ROUNDING = 1e-12  # relative rounding of a probe's outputs after its steps, discounted from their nonlinearity
MAX_PULSE_GAIN = 1e8  # the most a linear probe's pulse grows to match its responses to their outputs' baseline
LOCAL_AMPLITUDE = 1e-4  # relative probe size of a local linearisation (central differences: error ~ δ²)
LOCAL_ORDER_TOLERANCE = 1e-6  # σ_i / σ_1 of a state of a local linearisation: above the δ² ~ 1e-8 of its probes
FIT_TOLERANCE = 1e-6  # largest relative misfit of the realised Markov parameters of a linear subsystem


class IdentificationError(ValueError):
    """A subsystem whose responses cannot be realised as a discrete-time linear system; the message says why."""


@dataclass(frozen=True)
class Identification:
    """How one subsystem was identified (the analyze report's ``identification`` entry)."""

    subsystem: str
    method: str  # "ERA on held-input probes", or "none" (a source or a sink)
    order: int  # n, states of the realisation (without the output samples of ξ)
    fit_residual: float  # max |h_realised − h_measured| / max |h_measured| over every measured Markov parameter
    nonlinearity: float  # |(y_+ − y_0) + 2 (y_− − y_0)| / |y_+ − y_−|, largest over the probed coefficients
    exact: bool  # linear to rounding (else a local linearisation about the initial operating point)
    probes: int  # runs of the subsystem alone
    steps: int  # communication steps per probe (of the last Hankel size tried)
    singular_values: tuple[float, ...]  # of the scaled Hankel matrix, largest first (the first order + 2)
    role: str = "loop"  # "source" (no coupling feeds it), "sink" (none reads it): no state in the scheme

    def to_dict(self) -> dict:
        return {"method": self.method, "role": self.role, "order": self.order, "fit_residual": self.fit_residual,
                "nonlinearity": self.nonlinearity,
                "linearisation": "exact" if self.exact else "local", "probes": self.probes, "steps": self.steps,
                "singular_values": list(self.singular_values)}

    def describe(self) -> str:
        kind = "exact (linear to rounding)" if self.exact else "local linearisation about the initial point"
        return (f"{self.method}: order {self.order}, fit residual {self.fit_residual:.2g}, "
                f"nonlinearity {self.nonlinearity:.2g}, {kind}; {self.probes} probes of {self.steps} steps")


@dataclass(frozen=True)
class IdentifiedStep:
    """One communication step of an identified subsystem in the form of ``manager.analysis.discrete.SubsystemMap``:
    ``ξ_end = Φ ξ + Σ_q Γ[q] c_q``, ``y = C_y ξ_end + D_y w(H)``."""

    Phi: np.ndarray
    Gamma: np.ndarray  # (p + 1, n + n_fed_outputs, n_inputs)
    C_y: np.ndarray
    D_y: np.ndarray
    identification: Identification


@dataclass(frozen=True)
class Probe:
    """Runs of one subsystem alone from its initial state: ``restart`` gives it at t = 0, as built."""

    restart: Callable[[], Subsystem]
    span_ns: int  # its communication step
    w0: np.ndarray  # input values held (the initial operating point)
    fed_inputs: tuple[int, ...]  # inputs a coupling feeds (the others stay at w0)
    fed_outputs: tuple[int, ...]  # outputs that feed another subsystem
    rows: int  # p + 1 coefficients of the input polynomial

    def outputs(self, pulse: np.ndarray, steps: int) -> np.ndarray:
        """The fed outputs at the end of each of ``steps`` steps, ``pulse`` (rows, inputs) added to ``c`` in step 0."""
        sub = self.restart()
        held = np.zeros((self.rows, self.w0.size))
        held[0] = self.w0
        y = np.empty((steps, len(self.fed_outputs)))
        with np.errstate(all="ignore"):  # a response that overflows is judged by its values (markov_parameters)
            for k in range(steps):
                c = held + pulse if k == 0 else held
                try:
                    y[k] = sub.advance_values(k * self.span_ns, (k + 1) * self.span_ns, c)[list(self.fed_outputs)]
                except Exception as error:  # the component's own code failed (an FMU's status, a user's model)
                    raise IdentificationError(f"a probe failed at t = {(k + 1) * self.span_ns * 1e-9:.9g} s: "
                                              f"{type(error).__name__}: {error}") from None
        return y


def markov_parameters(probe: Probe, amplitude: float, steps: int, exact: bool
                      ) -> tuple[np.ndarray, float, float, int]:
    """``h`` (steps, fed outputs, rows · fed inputs; columns ``q``-major) from probes of ``δ = amplitude ·
    max(|w_0|, 1) / H^q``, the nonlinearity of the responses beyond rounding, their error (the same measure with the
    rounding: the noise of ``h`` relative to each column's response) and the number of probes. ``exact``: pulses ``+δ`` and
    ``−δ/2``, whose responses ``y_+, y_−`` about the baseline ``y_0`` satisfy ``(y_+ − y_0) + 2 (y_− − y_0) = 0`` for a
    linear subsystem (even and odd nonlinear terms both break it); else central differences ``±δ`` (error ~ δ²),
    their even part ``y_+ + y_− − 2 y_0`` the nonlinearity, and ``IdentificationError`` when ``h`` is not finite."""
    y0 = probe.outputs(np.zeros((probe.rows, probe.w0.size)), steps)
    H = probe.span_ns * 1e-9
    back = 0.5 if exact else 1.0  # the second pulse is −back · δ
    columns, nonlinearity, error, probes = [], 0.0, 0.0, 1
    with np.errstate(all="ignore"):  # responses that overflow are judged by their values
        for q in range(probe.rows):
            for i in probe.fed_inputs:
                delta = amplitude * max(abs(probe.w0[i]), 1.0) / H ** q
                pulse = np.zeros((probe.rows, probe.w0.size))
                pulse[q, i] = delta
                plus, minus = probe.outputs(pulse, steps), probe.outputs(-back * pulse, steps)
                probes += 2
                gain = _pulse_gain(y0, plus, minus) if exact else 1.0
                if gain > 1.0:  # a response below its outputs' baseline is exact only to their rounding: larger
                    delta, pulse = gain * delta, gain * pulse
                    plus, minus = probe.outputs(pulse, steps), probe.outputs(-back * pulse, steps)
                    probes += 2
                beyond_rounding, relative = _nonlinearity(y0, plus, minus, back)
                nonlinearity, error = max(nonlinearity, beyond_rounding), max(error, relative)
                columns.append((plus - minus) / ((1.0 + back) * delta))
    h = np.stack(columns, axis=2)
    if not exact and not np.all(np.isfinite(h)):
        raise IdentificationError("its responses to the probes are not finite")
    return h, nonlinearity, error, probes


def _pulse_gain(y0: np.ndarray, plus: np.ndarray, minus: np.ndarray) -> float:
    """How much larger a pulse must be for its weakest response after the pulse's step (the Markov parameters of the
    Hankel matrix: the step's own is the feedthrough ``D'``) to match its output's baseline (at most
    ``MAX_PULSE_GAIN``; 1 when every response does already, or none moves)."""
    response, baseline = np.max(np.abs(plus[1:] - minus[1:]), axis=0), np.max(np.abs(y0), axis=0)
    moved = (response > 0.0) & (baseline > 0.0)
    if not np.any(moved):
        return 1.0
    return float(np.clip(np.max(baseline[moved] / response[moved]), 1.0, MAX_PULSE_GAIN))


def _nonlinearity(y0: np.ndarray, plus: np.ndarray, minus: np.ndarray, back: float) -> tuple[float, float]:
    """``|(y_+ − y_0) + (y_− − y_0) / back|`` relative to ``|y_+ − y_−|``, largest over the outputs: above the rounding
    of their values (``ROUNDING`` times their size: a response far smaller than its output's baseline is exact only
    to that), and as it is."""
    even = np.max(np.abs((plus - y0) + (minus - y0) / back), axis=0)
    odd = np.max(np.abs(plus - minus), axis=0)
    size = np.max(np.abs(y0) + np.abs(plus) + np.abs(minus) / back, axis=0)
    scale = np.where(odd > 0.0, odd, np.inf)
    return (float(np.max(np.maximum(even - ROUNDING * size, 0.0) / scale, initial=0.0)),
            float(np.max(even / scale, initial=0.0)))


def eigensystem_realization(h: np.ndarray, rows: int, tolerance: float
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ERA (see the module text) of Markov parameters ``h`` (at least ``2 rows + 1``): ``A, B, C', D'`` and the
    singular values of the scaled Hankel matrix."""
    out_scale = np.max(np.abs(h[1:]), axis=(0, 2))  # of the Hankel matrix's entries (h_0 is not one)
    out_scale[out_scale == 0.0] = 1.0
    g = h / out_scale[None, :, None]
    in_scale = np.max(np.abs(g[1:]), axis=(0, 1))
    in_scale[in_scale == 0.0] = 1.0
    g = g / in_scale[None, None, :]
    p, m = g.shape[1:]
    H0 = np.block([[g[i + j + 1] for j in range(rows)] for i in range(rows)])
    H1 = np.block([[g[i + j + 2] for j in range(rows)] for i in range(rows)])
    U, sigma, Vt = np.linalg.svd(H0)
    n = int(np.sum(sigma > tolerance * sigma[0])) if sigma[0] > 0.0 else 0
    root = np.sqrt(sigma[:n])
    A = (U[:, :n].T @ H1 @ Vt[:n].T) / root[:, None] / root[None, :]
    B = (root[:, None] * Vt[:n, :m]) * in_scale[None, :]
    C = (U[:p, :n] * root[None, :]) * out_scale[:, None]
    return A, B, C, h[0], sigma


def realised_markov(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, steps: int) -> np.ndarray:
    """``D, C B, C A B, …``: the first ``steps`` Markov parameters of a realisation."""
    h, AkB = [D], B
    for _ in range(steps - 1):
        h.append(C @ AkB)
        AkB = A @ AkB
    return np.stack(h)


def identify(name: str, probe: Probe, n_outputs: int) -> IdentifiedStep:
    """The one-step map of subsystem ``name`` (``n_outputs`` outputs in all) identified from ``probe``: the Hankel
    matrix grows (``HANKEL_ROWS`` × 4 at a time, up to ``MAX_HANKEL_ROWS``) until its weakest state stands
    ``STATE_GAP`` above the probes' error, the next singular value (a slow subsystem's states differ little over a
    few steps: σ_n / σ_1 grows as r²). A subsystem no coupling feeds (a source: its outputs are forcing) or none
    reads (a sink) has no state in the loop: order 0, without probes."""
    if not probe.fed_inputs or not probe.fed_outputs:
        p, m = len(probe.fed_outputs), probe.rows * len(probe.fed_inputs)
        role = "source" if not probe.fed_inputs else "sink"
        report = Identification(name, "none", 0, 0.0, 0.0, True, 0, 0, (), role)
        return _step_map(probe, n_outputs, np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0)), np.zeros((p, m)),
                         report)
    rows, probes = HANKEL_ROWS, 0
    while True:
        steps = 2 * rows + 2 + VALIDATION_STEPS
        try:
            h, nonlinearity, error, count = markov_parameters(probe, 1.0, steps, exact=True)
            exact = nonlinearity <= LINEAR_TOLERANCE and bool(np.all(np.isfinite(h)))
        except IdentificationError:  # the component fails under probes of its inputs' size: small ones may do
            exact, nonlinearity, count = False, None, 0
        probes += count
        if exact:
            tolerance = max(ORDER_TOLERANCE, ERROR_MARGIN * error)
        else:
            h, local, error, count = markov_parameters(probe, LOCAL_AMPLITUDE, steps, exact=False)
            probes += count
            nonlinearity = local if nonlinearity is None else nonlinearity
            tolerance = max(LOCAL_ORDER_TOLERANCE, ERROR_MARGIN * error)
        A, B, C, D, sigma = eigensystem_realization(h, rows, tolerance)
        n = A.shape[0]
        gap = sigma[n - 1] / sigma[n] if 0 < n < sigma.size and sigma[n] > 0.0 else np.inf
        if not exact or gap >= STATE_GAP or rows >= MAX_HANKEL_ROWS:
            break
        rows *= 4
    scale = np.max(np.abs(h))
    residual = float(np.max(np.abs(realised_markov(A, B, C, D, steps) - h)) / scale) if scale > 0.0 else 0.0
    if not np.isfinite(residual) or residual > max(FIT_TOLERANCE, 10.0 * tolerance):
        raise IdentificationError(f"the realisation of order {n} misses its Markov parameters by "
                                  f"{residual:.3g} (relative): not a linear system of order up to "
                                  f"{rows * min(h.shape[1:])} at this step")
    report = Identification(name, "ERA on held-input probes", n, residual, nonlinearity,
                            exact, probes, steps, tuple(float(s) for s in sigma[:n + 2]))
    return _step_map(probe, n_outputs, A, B, C, D, report)


def _step_map(probe: Probe, n_outputs: int, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
              report: Identification) -> IdentifiedStep:
    """The realisation ``A, B, C', D'`` (columns: the fed inputs' coefficients, ``q``-major) as a one-step map of
    ``ξ = [s; y]`` (see the module text), every input and output of the subsystem in its place."""
    n, p = A.shape[0], len(probe.fed_outputs)
    Phi = np.zeros((n + p, n + p))
    Phi[:n, :n], Phi[n:, :n] = A, C
    Gamma = np.zeros((probe.rows, n + p, probe.w0.size))
    fed = list(probe.fed_inputs)
    for q in range(probe.rows):
        block = slice(q * len(fed), (q + 1) * len(fed))
        Gamma[q][:n, fed], Gamma[q][n:, fed] = B[:, block], D[:, block]
    C_y = np.zeros((n_outputs, n + p))
    C_y[list(probe.fed_outputs), n + np.arange(p)] = 1.0
    return IdentifiedStep(Phi, Gamma, C_y, np.zeros((n_outputs, probe.w0.size)), report)


def initial_inputs(plan: Plan, subsystems: dict[str, Subsystem]) -> list[np.ndarray]:
    """Every subsystem's input values at t_0 (plan order): the outputs at t_0 evaluated round by round as the plan's
    initialisation orders them (``Plan.init_rounds``), each with the inputs its sources have given so far."""
    outputs: list[np.ndarray | None] = [None] * len(plan.subsystems)

    def gathered(s: SubsystemPlan) -> np.ndarray:
        w = np.zeros(len(s.inputs))
        for feed in s.feeds:
            if outputs[feed.source] is not None:
                w[list(feed.inputs)] = outputs[feed.source][list(feed.outputs)]
        return w

    for round_ in plan.init_rounds:
        for step in round_:
            s = plan.subsystems[step.subsystem]
            outputs[s.index] = np.asarray(subsystems[s.name].output_values(gathered(s)), dtype=float)
    return [gathered(s) for s in plan.subsystems]


def identified_steps(plan: Plan, subsystems: dict[str, Subsystem], names: set[str],
                     fresh: Callable[[str], Subsystem], can_save: Callable[[str], bool]) -> dict[str, IdentifiedStep]:
    """The subsystems ``names`` (built, at t = 0) identified at their communication steps about the initial operating
    point; ``fresh(name)`` builds one anew, for a component that cannot save its state (``can_save``)."""
    w0 = initial_inputs(plan, subsystems)
    fed_outputs = {s.index: set() for s in plan.subsystems}
    for s in plan.subsystems:
        for feed in s.feeds:
            fed_outputs[feed.source].update(feed.outputs)
    result = {}
    for s in plan.subsystems:
        if s.name not in names:
            continue
        sub = subsystems[s.name]
        saveable = can_save(s.name)
        if saveable:
            saved = sub.save()

            def restart(sub=sub, saved=saved) -> Subsystem:
                sub.restore(saved)
                return sub
        else:
            def restart(name=s.name) -> Subsystem:
                return fresh(name)
        probe = Probe(restart, s.ratio * plan.base_step_ns, w0[s.index],
                      tuple(sorted(i for feed in s.feeds for i in feed.inputs)), tuple(sorted(fed_outputs[s.index])),
                      s.order + 1)
        try:
            result[s.name] = identify(s.name, probe, len(s.outputs))
        except IdentificationError as error:
            raise IdentificationError(f"subsystem {s.name} cannot be identified: {error}") from None
        finally:
            if saveable:
                sub.restore(saved)
    return result
