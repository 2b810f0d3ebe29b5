"""Feedback loops of FMUs whose modelDescriptions declare no output dependencies, as OSP system structures that
libcosim and zencosim both load: the same file for both tools.

* pythonfmu (:data:`PD_SOURCE`, :data:`PLANT_SOURCE`): a PD controller whose force is computed whenever it is read
  (a getter: ``force = kp (setpoint - position) - kd velocity``, direct feedthrough), and a mass on a spring and
  damper, released from 0.5 m, that reports its velocity and the position its compliant mount shows,
  ``x_mount = x + f / k_mount`` (a getter too: direct feedthrough of its force input). Force one way, position and
  velocity back: an algebraic loop at the same instant, which libcosim's initialisation passes do not solve (the
  fixed-point iteration contracts by kp / k_mount = 0.05 a pass), so the initial values say how many passes ran.
* crane-fmu's ``DrivingForce.fmu`` and ``HarmonicOscillator6D.fmu`` (made with component-model): the driving force
  on three axes of the oscillator, the oscillator's velocities back to the force's ``v_osc`` inputs.

``tests.interop.pythonfmu_pair.write_plain_osp`` writes either as plain ``VariableConnection``s.
"""
from __future__ import annotations

PD_SOURCE = '''\
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PDController(Fmi2Slave):
    """force = kp (setpoint - position) - kd velocity, at the instant it is read."""

    author = "zencosim tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.kp, self.kd, self.setpoint = 20.0, 4.0, 1.0
        self.position, self.velocity = 0.0, 0.0
        for name in ("kp", "kd", "setpoint"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("position", causality=Fmi2Causality.input))
        self.register_variable(Real("velocity", causality=Fmi2Causality.input))
        self.register_variable(Real("force", causality=Fmi2Causality.output,
                                    getter=lambda: self.kp * (self.setpoint - self.position) - self.kd * self.velocity))

    def do_step(self, current_time, step_size):
        return True
'''

PLANT_SOURCE = '''\
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class MassSpring(Fmi2Slave):
    """m a = f - k x - c v by symplectic Euler, from x = 0.5 m at rest; x_mount = x + f / k_mount."""

    author = "zencosim tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m, self.k, self.c, self.k_mount = 2.0, 40.0, 0.5, 400.0
        self.x, self.v, self.f = 0.5, 0.0, 0.0
        for name in ("m", "k", "c", "k_mount"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("f", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))
        self.register_variable(Real("v", causality=Fmi2Causality.output))
        self.register_variable(Real("x_mount", causality=Fmi2Causality.output,
                                    getter=lambda: self.x + self.f / self.k_mount))

    def do_step(self, current_time, step_size):
        self.v += step_size * (self.f - self.k * self.x - self.c * self.v) / self.m
        self.x += step_size * self.v
        return True
'''

# (source simulator, output, target simulator, input)
PD_CONNECTIONS = (("controller", "force", "plant", "f"), ("plant", "x_mount", "controller", "position"),
                  ("plant", "v", "controller", "velocity"))
CRANE_CONNECTIONS = tuple(("drive", f"f[{i}]", "osc", f"f[{i}]") for i in range(3)) + tuple(
    ("osc", f"v[{i}]", "drive", f"v_osc[{i}]") for i in range(3))

