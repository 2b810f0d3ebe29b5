"""A subsystem: one model, one integrator, its state, and the communication-step interface.

``advance`` integrates from one communication point to the next with a fixed micro-step, evaluating
the input polynomial at every micro-step, and returns the outputs at the new point. Outputs with
direct feedthrough are evaluated with the input polynomial at the *end* of the step, i.e. with the
extrapolated input ``ũ_{k+1} = p_k(t_{k+1})`` (paper 002 Eq. 4): for zero-order extrapolation that is
``u_k``. This choice decides the discrete poles of the co-simulation (see docs/numerics.md).

A linear, time-invariant model (``linear_dynamics()``: no external forces of time, no nonlinear
effect) under an integrator that is a linear map per micro-step (``linear_step``) is advanced by the
composition of its micro-steps over the input polynomial (``subsystems.integrators.base.composed_linear_step``):
the same integrator and micro-step in one matrix product per communication step (it differs from
stepping only by rounding). This is the one-step map the exact discrete analysis uses. A small one runs that
step and its outputs as one straight-line function over floats (``subsystems.straight_line``), on every bus.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zencosim.subsystems.inputs import InputPolynomial
from zencosim.subsystems.integrators.base import composed_linear_step
from zencosim.subsystems.integrators.own_solver import OwnSolver
from zencosim.subsystems.ports import Port
from zencosim.subsystems.straight_line import StepText, StraightLineStep, step_text, straight_line_step


@dataclass(frozen=True)
class SavedState:
    """A complete, immutable copy of a subsystem's state at one communication point."""

    t_ns: int
    z: bytes  # float64 little-endian state vector, exact to the bit
    model: object = None  # the state a model keeps itself (a co-simulation FMU's), when it has one


class Subsystem:
    """A model advanced by an integrator with a fixed micro-step [ns] (``whole_steps``: every step is one micro-step,
    whatever its length — a co-simulation component in a run whose macro-steps vary takes one doStep per macro-step,
    as libcosim's ECCO does: ``manager.scheme.energy_step``)."""

    def __init__(self, name: str, model, integrator_cls: type, micro_step_ns: int, whole_steps: bool = False) -> None:
        if micro_step_ns <= 0:
            raise ValueError(f"subsystem {name}: micro_step must be positive, got {micro_step_ns} ns")
        self.name = name
        self.model = model
        self.micro_step_ns = micro_step_ns
        self.whole_steps = whole_steps
        self._linear = _linear_dynamics(model, integrator_cls)
        z0 = model.initial_state()
        # a linear model's state is the head of s = [z, w], the vector its outputs are one product of
        self._s = np.concatenate((z0, np.zeros(len(model.inputs)))) if self._linear is not None else None
        self.z = z0 if self._s is None else self._s[:z0.size]
        self.t_ns = 0
        self.w = np.zeros(len(model.inputs))  # input values at t_ns, as the last step or INIT used them (floats)
        self.integrator = integrator_cls(model, self.z)
        self._steps: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}  # (micro-steps, rows) -> (Φ^m, Ψ)
        # (micro-steps, rows) -> the step as straight-line code, None where numpy's products are cheaper
        self._straight: dict[tuple[int, int], StraightLineStep | None] = {}

    @property
    def inputs(self) -> tuple[Port, ...]:
        return self.model.inputs

    @property
    def outputs(self) -> tuple[Port, ...]:
        return self.model.outputs

    @property
    def effects(self) -> tuple[str, ...]:
        return self.model.effects

    def output_values(self, w: np.ndarray) -> np.ndarray:
        """Outputs at the current time with input values ``w``."""
        self.w = w
        return self.model.outputs_at(self.t_ns * 1e-9, self.z, w)

    def advance(self, t0_ns: int, t1_ns: int, inputs: InputPolynomial) -> np.ndarray:
        """Integrate from ``t0`` to ``t1`` [ns] and return the outputs at ``t1``."""
        return np.asarray(self.advance_values(t0_ns, t1_ns, inputs.coefficients), dtype=float)

    def advance_values(self, t0_ns: int, t1_ns: int, coefficients: np.ndarray | list[float]
                       ) -> list[float] | np.ndarray:
        """``advance`` over the input polynomial of ``coefficients`` (its rows, as ``InputPolynomial`` takes them, or
        a zero-order polynomial's values as a list of floats), the outputs at ``t1`` as the step computes them: a
        list of floats from a straight-line step, else the model's array (the in-process scheme's call:
        ``manager.bus.inproc.DirectCalls``)."""
        if t0_ns != self.t_ns:
            raise ValueError(f"subsystem {self.name}: asked to advance from t = {t0_ns} ns but it is at {self.t_ns} ns")
        span = t1_ns - t0_ns
        h_ns = span if self.whole_steps and span > 0 else self.micro_step_ns
        if span <= 0 or span % h_ns:
            raise ValueError(f"subsystem {self.name}: step of {span} ns is not a positive multiple "
                             f"of the micro-step {h_ns} ns")
        h = h_ns * 1e-9
        listed = type(coefficients) is list
        if self._linear is not None:  # z ← Φ^m z + Ψ c in place; the outputs from s = [z, w(t1)] as it stands
            key = (span // h_ns, 1 if listed else coefficients.shape[0])
            straight = self._straight.get(key, False)
            if straight is False:
                straight = self._straight_step(key, h, span * 1e-9)
            if straight is not None:
                y, self.w = straight(self.z, coefficients if listed else coefficients.ravel().tolist())
                self.t_ns = t1_ns
                return y
        if listed:
            coefficients = np.array([coefficients], dtype=float).reshape(1, len(self.inputs))
        if self._linear is not None:
            composed = self._steps.get(key)  # the step's maps, once composed
            Phi_m, Psi = composed if composed is not None else self._composed_step(*key, h)
            z = self.z
            np.add(Phi_m.dot(z), Psi.dot(coefficients.ravel()), z)  # out=z, positional: no keyword parsing each step
            self.t_ns = t1_ns
            self.w = self._s[z.size:] = InputPolynomial(coefficients).at(span * 1e-9)
            return self.model.outputs_of(t1_ns * 1e-9, self._s)
        inputs = InputPolynomial(coefficients)
        step = self.integrator.step
        for j in range(span // h_ns):
            offset_ns = j * h_ns
            step((t0_ns + offset_ns) * 1e-9, offset_ns * 1e-9, h, inputs)
        self.t_ns = t1_ns
        self.w = inputs.at(span * 1e-9)
        return self.model.outputs_at(t1_ns * 1e-9, self.z, self.w)

    def _straight_step(self, key: tuple[int, int], h: float, span_s: float) -> StraightLineStep | None:
        """The straight-line step of ``key`` (micro-steps, rows) over ``span_s`` seconds, or None; cached."""
        Phi_m, Psi = self._composed_step(*key, h)
        self._straight[key] = straight_line_step(Phi_m, Psi, key[1], span_s, *self.model.output_matrix())
        return self._straight[key]

    def step_text(self, span_ns: int, prefix: str, start_ns: str) -> StepText | None:
        """The statements of the step ``advance_values`` takes over ``span_ns`` with zero-order inputs (its names
        prefixed with ``prefix``; ``start_ns`` the text of an expression giving the step's start [ns], an int), or
        None where it has none: a linear model's straight-line step (``subsystems.straight_line``: the same products,
        in the same order), or a model's own (a co-simulation FMU's calls under the ``own`` integrator,
        ``step_text`` of the model). For a loop that runs the step itself (``manager.scheme.compiled``), which hands
        the state it leaves to ``took_steps``."""
        h_ns = self.micro_step_ns
        if span_ns <= 0 or span_ns % h_ns:
            return None
        if self._linear is not None:
            Phi_m, Psi = self._composed_step(span_ns // h_ns, 1, h_ns * 1e-9)
            return step_text(Phi_m, Psi, 1, span_ns * 1e-9, *self.model.output_matrix(), prefix=prefix)
        if isinstance(self.integrator, OwnSolver) and hasattr(self.model, "step_text"):
            return self.model.step_text(prefix, start_ns, span_ns // h_ns, h_ns)
        return None

    def took_steps(self, t_ns: int, z: list[float], w: list[float]) -> None:
        """Take the state ``z`` and the input values ``w`` at ``t_ns`` that the steps of ``step_text`` left, run
        elsewhere: as if ``advance_values`` had taken them."""
        self.z[:] = z
        self.t_ns = t_ns
        self.w = w

    def free_step(self, span_ns: int) -> np.ndarray | None:
        """The matrix ``advance`` multiplies the state by over a step of ``span_ns`` when the model is linear and
        has no inputs (then that is the whole step), else None."""
        if self._linear is None or len(self.inputs):
            return None
        return self._composed_step(span_ns // self.micro_step_ns, 1, self.micro_step_ns * 1e-9)[0]

    def _composed_step(self, micro_steps: int, rows: int, h: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ^m, Ψ)`` with ``Ψ`` flattened to ``(2n, rows * n_inputs)``, cached."""
        key = (micro_steps, rows)
        if key not in self._steps:
            Phi_m, Psi = composed_linear_step(type(self.integrator), *self._linear, h, micro_steps, rows)
            self._steps[key] = (Phi_m, Psi.reshape(Phi_m.shape[0], -1))
        return self._steps[key]

    def project(self, corrections: np.ndarray) -> np.ndarray:
        """Projection step of a rigid joint (paper 003 Eqs. 30, 55, 68): correct the state by
        ``corrections`` (per joint side: position then velocity correction, one value per axis; see the
        model's ``project``) and return the outputs with the input values of the last step."""
        self.model.project(self.z, corrections)
        return self.model.outputs_at(self.t_ns * 1e-9, self.z, self.w)

    def save(self) -> SavedState:
        own = self.model.save_state() if hasattr(self.model, "save_state") else None
        return SavedState(self.t_ns, self.z.astype("<f8").tobytes(), own)

    def restore(self, saved: SavedState) -> None:
        self.z[:] = np.frombuffer(saved.z, dtype="<f8")
        self.t_ns = saved.t_ns
        if hasattr(self.model, "restore_state"):
            self.model.restore_state(saved.model)


def _linear_dynamics(model, integrator_cls: type) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A_a, B_a)`` when the model is linear and time-invariant (and gives its outputs from ``s = [z, w]``:
    ``outputs_of``) and the integrator a linear map."""
    if not hasattr(integrator_cls, "linear_step") or not hasattr(model, "linear_dynamics") \
            or not hasattr(model, "outputs_of"):
        return None
    try:
        return model.linear_dynamics()
    except ValueError:  # external forces of time or nonlinear effects: step micro-step by micro-step
        return None
