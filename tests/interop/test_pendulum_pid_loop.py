"""A pythonfmu pendulum under a pythonfmu PID controller (a loop libcosim runs, though
neither FMU declares its outputs' ``dependencies``): zencosim gives libcosim's answer on the same OSP file, single-
and multi-rate, to ``AGREEMENT`` (1e-12) of each signal's range, as tests/interop/test_feedthrough_loops.py checks
the PD loop (its OSP writer and comparison are reused here).

The pendulum is nonlinear (``sin θ``) and swings 0.6 rad from rest to the setpoint 0.3 rad, so the loop is
compared beyond its linear range. The controller's torque is a getter (direct feedthrough of the angle and rate
it reads) while its integral of the error advances in its doStep.
"""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu", reason="pythonfmu exports the loop's FMUs (pip install pythonfmu)")
pytest.importorskip("libcosimpy", reason="libcosim is the oracle (pip install libcosimpy)")

from tests.interop.measures import AGREEMENT  # noqa: E402
from tests.interop.pythonfmu_pair import build_fmu  # noqa: E402
from tests.interop.test_feedthrough_loops import deviations, run_zencosim, system  # noqa: E402

PID_SOURCE = '''\
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PIDController(Fmi2Slave):
    """torque = kp e + ki * integral of e dt - kd rate, e = setpoint - angle, at the instant it is read; the
    integral by rectangles, the error of a step's start times the step."""

    author = "zencosim tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.kp, self.ki, self.kd, self.setpoint = 8.0, 4.0, 1.5, 0.3
        self.angle, self.rate, self.integral = 0.0, 0.0, 0.0
        for name in ("kp", "ki", "kd", "setpoint"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("angle", causality=Fmi2Causality.input))
        self.register_variable(Real("rate", causality=Fmi2Causality.input))
        self.register_variable(Real("torque", causality=Fmi2Causality.output, getter=lambda: (
            self.kp * (self.setpoint - self.angle) + self.ki * self.integral - self.kd * self.rate)))

    def do_step(self, current_time, step_size):
        self.integral += (self.setpoint - self.angle) * step_size
        return True
'''

PENDULUM_SOURCE = '''\
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Pendulum(Fmi2Slave):
    """m L^2 dω/dt = torque - m g L sin θ - c ω by symplectic Euler, from θ = -0.3 rad at rest."""

    author = "zencosim tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m, self.length, self.g, self.c = 1.0, 0.5, 9.81, 0.05
        self.angle, self.rate, self.torque = -0.3, 0.0, 0.0
        for name in ("m", "length", "g", "c"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("torque", causality=Fmi2Causality.input))
        self.register_variable(Real("angle", causality=Fmi2Causality.output))
        self.register_variable(Real("rate", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        inertia = self.m * self.length ** 2
        self.rate += step_size * (self.torque - self.m * self.g * self.length * math.sin(self.angle)
                                  - self.c * self.rate) / inertia
        self.angle += step_size * self.rate
        return True
'''

DURATION = 2.0  # [s]
# (source simulator, output, target simulator, input)
CONNECTIONS = (("controller", "torque", "pendulum", "torque"), ("pendulum", "angle", "controller", "angle"),
               ("pendulum", "rate", "controller", "rate"))
# simulator -> (the variables compared, its stepSize in base steps: single rate, multi-rate)
VARIABLES = {"controller": (("torque",), (1, 2)), "pendulum": (("angle", "rate"), (1, 1))}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    build = tmp_path_factory.mktemp("pendulum_build")
    return {"controller": build_fmu(build, "zencosim_pid_controller", PID_SOURCE),
            "pendulum": build_fmu(build, "zencosim_pendulum", PENDULUM_SOURCE)}


@pytest.mark.parametrize("rate", [0, 1], ids=["single-rate", "multi-rate"])
def test_a_pythonfmu_pendulum_under_a_pid_controller_gives_libcosims_answer(fmus, rate, tmp_path):
    osp = system(tmp_path, fmus, VARIABLES, CONNECTIONS, rate)
    result = run_zencosim(osp, VARIABLES, DURATION)
    found = deviations(osp, VARIABLES, result, DURATION)
    assert max(found.values()) <= AGREEMENT, found
    angle = result.signal("angle").values
    assert angle[0] == -0.3 and angle.max() > 0.3  # it swings past the setpoint: the loop closes
