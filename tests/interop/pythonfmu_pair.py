"""A controller exported with pythonfmu driving the example oscillator FMU: the zencosim scene and the OSP file.

:func:`build_controller` writes :data:`CONTROLLER_SOURCE` (a PI position controller written as pythonfmu's
authors show: an ``Fmi2Slave`` with registered variables, its parameters FMU parameters) and exports it with
pythonfmu's builder (:func:`build_fmu`, any such source). :func:`write_scene` writes the zencosim TOML scene and
:func:`write_osp` the OSP system structure (:func:`write_plain_osp`, any system of plain connections) of one
system: the plant (``zencosim.examples``' oscillator FMU: m, k, c, force input ``f_in``) and the controller,
coupled by two plain connections, plant ``x`` -> controller ``position`` and controller ``force`` -> plant
``f_in`` (zencosim: ``type = "signal"``; OSP: ``VariableConnection`` with no power bond).

pythonfmu's FMUs declare no units (its ``Real`` has no unit attribute); the scene gives them
(``units = { position = "m", force = "N" }``), libcosim needs none. Their binary does not link libpython:
its ``Py*`` symbols resolve against the process that loads it, so it runs in the host's interpreter (its
``sys.modules`` and ``sys.path`` included) and only in a Python process (fmpy, libcosimpy and zencosim all are).
"""
from __future__ import annotations

import shutil
from pathlib import Path

PLANT_START = {"m": 2.0, "k": 1.0, "c": 0.5}  # kg, N/m, N s/m: x(0) = v(0) = 0
CONTROLLER_START = {"kp": 20.0, "ki": 5.0, "setpoint": 1.0}  # N/m, N/(m s), m
STEP = 0.01  # [s] the macro step, every FMU's step
DURATION = 5.0  # [s]
PLANT_OUTPUTS = ("x", "v", "a")
CONTROLLER_OUTPUTS = ("force",)

CONTROLLER_SOURCE = '''\
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PIController(Fmi2Slave):
    """force = kp e + ki * integral of e dt, e = setpoint - position; the integral by rectangles, the
    error of a step's start times the step."""

    author = "zencosim tests"
    description = "PI position controller: measured position in, force out"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.kp = 1.0
        self.ki = 0.0
        self.setpoint = 0.0
        self.position = 0.0
        self.integral = 0.0
        self.force = 0.0
        for name in ("kp", "ki", "setpoint"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("position", causality=Fmi2Causality.input))
        self.register_variable(Real("force", causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        self.force = self.kp * (self.setpoint - self.position)

    def do_step(self, current_time, step_size):
        error = self.setpoint - self.position
        self.integral += error * step_size
        self.force = self.kp * error + self.ki * self.integral
        return True
'''


def build_fmu(directory: Path, module: str, text: str) -> Path:
    """Export the ``Fmi2Slave`` of the source ``text``, written as ``module``.py, with pythonfmu's builder into
    ``directory``; return the FMU (named after the class)."""
    from pythonfmu.builder import FmuBuilder

    source = directory / "source" / f"{module}.py"
    source.parent.mkdir(parents=True, exist_ok=True)
    source.write_text(text)
    return Path(FmuBuilder.build_FMU(source, dest=directory))


def build_controller(directory: Path) -> Path:
    """Export the controller with pythonfmu's builder into ``directory``; return ``PIController.fmu``."""
    return build_fmu(directory, "zencosim_pi_controller", CONTROLLER_SOURCE)


def write_scene(directory: Path, plant: Path, controller: Path) -> Path:
    """The zencosim scene of the pair, ``directory/pi_plant.toml``, with copies of both FMUs beside it."""
    for fmu in (plant, controller):
        if fmu.parent != directory:
            shutil.copy(fmu, directory / fmu.name)

    def table(values: dict) -> str:
        return "{ " + ", ".join(f"{k} = {v!r}" for k, v in values.items()) + " }"

    scene = directory / "pi_plant.toml"
    scene.write_text(f"""name = "pi_plant"
description = "a PI controller exported with pythonfmu positions the example oscillator FMU"
[manager]
duration = {DURATION!r}
macro_step = {STEP!r}
[outputs]
reference = "none"
[subsystems.plant]
model = "fmu"
fmu = "{plant.name}"
micro_step = {STEP!r}
start = {table(PLANT_START)}
outputs = "all"
[subsystems.controller]
model = "fmu"
fmu = "{controller.name}"
micro_step = {STEP!r}
start = {table(CONTROLLER_START)}
units = {{ position = "m", force = "N" }}
outputs = "all"
[couplings.measured]
type = "signal"
output = "plant.x"
input = "controller.position"
[couplings.actuation]
type = "signal"
output = "controller.force"
input = "plant.f_in"
""")
    return scene


def write_osp(directory: Path, plant: Path, controller: Path) -> Path:
    """The same system as an OSP system structure, ``directory/OspSystemStructure.xml``: plain
    ``VariableConnection``s, the start values as ``InitialValues``."""
    return write_plain_osp(directory, STEP, {"plant": (plant, STEP, PLANT_START),
                                             "controller": (controller, STEP, CONTROLLER_START)},
                           (("plant", "x", "controller", "position"), ("controller", "force", "plant", "f_in")))


def write_plain_osp(directory: Path, base_step: float, simulators: dict[str, tuple[Path, float, dict]],
                    connections: tuple[tuple[str, str, str, str], ...]) -> Path:
    """``directory/OspSystemStructure.xml``: ``simulators`` (name -> (FMU, stepSize [s], start values as
    ``InitialValues``), the FMUs copied beside it) joined by one plain ``VariableConnection`` per connection
    (source simulator, output, target simulator, input)."""
    def simulator(name: str, fmu: Path, step: float, start: dict) -> str:
        values = "".join(f'\n        <InitialValue variable="{k}"><Real value="{float(v)!r}"/></InitialValue>'
                         for k, v in start.items())
        return (f'\n    <Simulator name="{name}" source="{fmu.name}" stepSize="{step!r}">'
                f"\n      <InitialValues>{values}\n      </InitialValues>\n    </Simulator>")

    for fmu, _, _ in simulators.values():
        if fmu.parent != directory:
            shutil.copy(fmu, directory / fmu.name)
    elements = "".join(simulator(name, *description) for name, description in simulators.items())
    links = "".join(f'\n    <VariableConnection>\n      <Variable simulator="{s}" name="{o}"/>'
                    f'\n      <Variable simulator="{t}" name="{i}"/>\n    </VariableConnection>'
                    for s, o, t, i in connections)
    path = directory / "OspSystemStructure.xml"
    path.write_text(f"""<?xml version="1.0" encoding="utf-8"?>
<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
  <StartTime>0.0</StartTime>
  <BaseStepSize>{base_step!r}</BaseStepSize>
  <Algorithm>fixedStep</Algorithm>
  <Simulators>{elements}
  </Simulators>
  <Connections>{links}
  </Connections>
</OspSystemStructure>
""")
    return path
