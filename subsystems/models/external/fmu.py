"""FMUs as components, through fmpy: FMI 2.0 and 3.0 Co-Simulation, FMI 2.0 Model Exchange.

:func:`describe_fmu` reads an FMU's modelDescription at scene time: its real variables with causality,
unit (resolved through the unit definitions' base-unit exponents, factor and offset, or read as an SI
unit string) and the outputs' direct dependence on inputs (ModelStructure); its interfaces and whether it can save and
restore its state; its GUID (FMI 3.0: instantiation token) and the sha256 of the file, which identify
it to the other processes of a run. :func:`open_fmu` instantiates it for one subsystem.

Inputs over a communication step: zencosim sets the inputs at every micro-step (the extrapolation
polynomial evaluated at the micro-step's start) and calls ``doStep`` once per micro-step, rather than
handing the polynomial's derivatives to an FMU that can interpolate inputs: every FMU supports it, the
inputs are evaluated where zencosim's own integrators evaluate them (a CS FMU with symplectic Euler
inside reproduces the built-in model), and the micro-step is the scene's to choose.

Values are exchanged through ctypes arrays allocated once per instance; FMI calls go through fmpy's
low-level functions, which raise on an error status; that error is re-raised as :class:`FmuError`
naming the FMU, the call, the status and the simulated time. A step written into a generated loop
(``FmuCoSimulation.step_text``) makes its FMI calls in one foreign call where a C compiler is at hand
(``fmi_steps``).
"""
from __future__ import annotations

import ctypes
import hashlib
import math
import shutil
import tempfile
import weakref
import zipfile
from pathlib import Path

import numpy as np

from zencosim.subsystems.models.external.component import ComponentDescription, Variable
from zencosim.subsystems.models.external.fmi_steps import TERMINATE, FmiSteps, steps_function
from zencosim.subsystems.straight_line import NativeStep, StepText
from zencosim.subsystems.units import BASE, UnitError, exponents

INTERFACES = {"co-simulation": "coSimulation", "model-exchange": "modelExchange"}
REAL_TYPES = ("Real", "Float64")
_WARNING = 1  # fmi2Warning and fmi3Warning: a status above it (discard, error, fatal) fails the call
FMI2_FALSE = ctypes.c_int(0)  # fmi2Boolean, as a bare call passes it (_bare)
# FMI type -> (kind, the fmpy setter and getter of an FMI 2.0 or 3.0 instance): Integer and Boolean variables
# are exchanged as float64 values like every other and converted at the FMU's boundary
DISCRETE_TYPES = {"Integer": ("Integer", "Integer"), "Int32": ("Integer", "Int32"), "Int64": ("Integer", "Int64"),
                  "Boolean": ("Boolean", "Boolean")}


class FmuError(RuntimeError):
    """An FMU that cannot be used, or an FMI call that failed; the message names the FMU."""


class FmuFileError(FmuError):
    """A file that cannot be read as an FMU at all: missing, not a zip archive, no readable modelDescription."""


def describe_fmu(path: Path, interface: str | None) -> ComponentDescription:
    """The FMU at ``path`` with the interface asked for (``"co-simulation"``, ``"model-exchange"``; None:
    co-simulation when it offers it); :class:`FmuError` saying why it cannot be used."""
    model = _model_description(path)
    version = model.fmiVersion.split(".")[0]
    offered = [name for name, attribute in INTERFACES.items() if getattr(model, attribute) is not None]
    chosen = interface or (offered[0] if offered else None)
    if chosen not in offered:
        raise FmuError(f"FMU {path}: offers {' and '.join(offered) or 'no interface'}, not {chosen}")
    if chosen == "model-exchange" and version != "2":
        raise FmuError(f"FMU {path}: Model Exchange is supported for FMI 2.0; this FMU is FMI {model.fmiVersion}")
    if chosen == "model-exchange" and model.numberOfEventIndicators:
        raise FmuError(f"FMU {path}: declares {model.numberOfEventIndicators} event indicator(s); zencosim's "
                       "integrators do not locate events: use its Co-Simulation interface")
    capability = getattr(model, INTERFACES[chosen])
    identifier = capability.modelIdentifier
    binary = _binary_name(version, identifier)
    with zipfile.ZipFile(path) as archive:
        if binary not in archive.namelist():
            raise FmuError(f"FMU {path}: has no binary for this platform ({binary})")
    units = {unit.name: unit for unit in model.unitDefinitions}
    relative_quantities = _relative_quantities(path)
    dependencies = {unknown.variable.name: unknown.dependencies for unknown in model.outputs}
    variables = {}
    for v in model.modelVariables:
        if v.type in DISCRETE_TYPES:
            variables[v.name] = Variable(v.name, v.causality, None, None, "an Integer or Boolean has no unit",
                                         kind=DISCRETE_TYPES[v.type][0])
            continue
        if v.type not in REAL_TYPES:
            continue
        declared = v.declaredType
        unit = v.unit or (declared.unit if declared is not None else None)
        relative = v.name in relative_quantities if v.relativeQuantity is None else bool(v.relativeQuantity)
        relative = relative or bool(declared is not None and getattr(declared, "relativeQuantity", False))
        found, factor, offset, problem = _si_exponents(unit, units, relative)
        depends = dependencies.get(v.name)
        low, high = (_bound(v, declared, name, factor, offset) for name in ("min", "max"))
        variables[v.name] = Variable(v.name, v.causality, unit, found, problem,
                                     None if depends is None else tuple(d.name for d in depends), factor, offset,
                                     minimum=-math.inf if low is None else low,
                                     maximum=math.inf if high is None else high)
    kind = f"FMI {model.fmiVersion} {'Co-Simulation' if chosen == 'co-simulation' else 'Model Exchange'}"
    can_save = chosen == "model-exchange" or bool(capability.canGetAndSetFMUstate)
    variable_step = chosen == "model-exchange" or bool(capability.canHandleVariableCommunicationStepSize)
    return ComponentDescription(kind, "ode" if chosen == "model-exchange" else "co-simulation", variables, can_save,
                                identity=(("guid", model.guid), ("sha256", _sha256(path))), variable_step=variable_step)


def _model_description(path: Path):
    from fmpy import read_model_description
    if not path.is_file():
        raise FmuFileError(f"FMU {path}: no such file")
    if not zipfile.is_zipfile(path):
        raise FmuFileError(f"FMU {path}: not an FMU (not a zip archive)")
    try:
        model = read_model_description(str(path), validate=False)
    except Exception as error:  # fmpy raises plain exceptions for any malformed part
        raise FmuFileError(f"FMU {path}: its modelDescription.xml cannot be read: {error}") from None
    if model.fmiVersion not in ("2.0", "3.0"):
        raise FmuError(f"FMU {path}: FMI version {model.fmiVersion}; expected 2.0 or 3.0")
    return model


def _relative_quantities(path: Path) -> set[str]:
    """The variables whose own element says ``relativeQuantity="true"`` (fmpy 0.3 reads the attribute of a
    type definition, but not of a variable)."""
    from lxml import etree  # fmpy's dependency
    parser = etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False)
    with zipfile.ZipFile(path) as archive:
        root = etree.fromstring(archive.read("modelDescription.xml"), parser)
    found = set()
    for element in root.iterfind("ModelVariables/*"):
        value = element.find("Real") if element.tag == "ScalarVariable" else element  # FMI 2.0, 3.0
        if value is not None and value.get("relativeQuantity") in ("true", "1"):
            found.add(element.get("name"))
    return found


def _bound(variable, declared, name: str, factor: float, offset: float) -> float | None:
    """A variable's ``min`` or ``max`` (its own, else its type's) in SI; None when it declares none (or one that
    is not a number)."""
    raw = getattr(variable, name, None)
    if raw is None and declared is not None:
        raw = getattr(declared, name, None)
    try:
        value = float(raw)
    except (TypeError, ValueError):
        return None
    return factor * value + offset if math.isfinite(value) else None


def _binary_name(version: str, identifier: str) -> str:
    platform = "linux64" if version == "2" else "x86_64-linux"
    return f"binaries/{platform}/{identifier}.so"


def _si_exponents(unit: str | None, definitions: dict,
                  relative: bool = False) -> tuple[tuple[int, ...] | None, float, float, str | None]:
    """The SI exponents of a variable's unit with the factor and offset that convert its values to SI
    (value_SI = factor * value + offset), from its unit definition (FMI's BaseUnit; a relative quantity,
    such as a temperature difference, ignores the offset) or, without a definition, from the unit's name
    read as a coherent SI unit (factor 1, offset 0); else (None, 1, 0, why)."""
    if not unit:
        return None, 1.0, 0.0, "declares no unit"
    definition = definitions.get(unit)
    base = definition.baseUnit if definition is not None else None
    if base is not None:
        factor, offset = float(base.factor), 0.0 if relative else float(base.offset)
        if not (np.isfinite(factor) and np.isfinite(offset)) or factor == 0.0:
            return None, 1.0, 0.0, f"unit {unit!r} has factor {factor:g} and offset {offset:g}: not a conversion"
        return tuple(int(getattr(base, name)) for name in BASE), factor, offset, None
    try:
        return exponents(unit), 1.0, 0.0, None
    except UnitError as error:
        return None, 1.0, 0.0, f"unit {error}"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class _FmuInstance:
    """One instance of an FMU, exchanging the given inputs and outputs as float64 arrays."""

    def __init__(self, path: Path, description: ComponentDescription, start: dict[str, float],
                 inputs: tuple[str, ...], outputs: tuple[str, ...], instance_name: str) -> None:
        from fmpy import read_model_description
        self.path = path
        model = read_model_description(str(path), validate=False)
        self.version = model.fmiVersion.split(".")[0]
        self.references = {v.name: v.valueReference for v in model.modelVariables}
        self.directory = tempfile.mkdtemp(prefix="zencosim-fmu-")
        weakref.finalize(self, shutil.rmtree, self.directory, True)
        with zipfile.ZipFile(path) as archive:
            archive.extractall(self.directory)
        try:
            self.fmu = self._instantiate(model, description, instance_name)
        except Exception as error:  # noqa: BLE001 (fmpy raises a plain Exception, ctypes an OSError)
            python_fmu = "pythonfmu" in (model.generationTool or "").lower()  # a C FMU's cause is not packages
            hint = "a Python FMU (pythonfmu) needs its packages in this interpreter; " if python_fmu else ""
            raise FmuError(f"FMU {path.name}: cannot be instantiated ({type(error).__name__}: {error}); {hint}fmpy's "
                           "debug log says more (fmpy simulate --debug-logging)") from None
        types = {v.name: v.type for v in model.modelVariables}
        # the real inputs and outputs through preallocated ctypes arrays; Integer and Boolean ones apart
        self._real_u = [i for i, n in enumerate(inputs) if types[n] in REAL_TYPES]
        self._real_y = [i for i, n in enumerate(outputs) if types[n] in REAL_TYPES]
        self._discrete_u = self._discrete(inputs, types, "set")
        self._discrete_y = self._discrete(outputs, types, "get")
        self._n_outputs = len(outputs)
        self._inputs = (ctypes.c_uint * len(self._real_u))(*(self.references[inputs[i]] for i in self._real_u))
        self._outputs = (ctypes.c_uint * len(self._real_y))(*(self.references[outputs[i]] for i in self._real_y))
        self._u = (ctypes.c_double * len(self._real_u))()
        self._y = (ctypes.c_double * len(self._real_y))()
        self._u_view = np.ctypeslib.as_array(self._u) if self._real_u else np.zeros(0)
        self._y_view = np.ctypeslib.as_array(self._y) if self._real_y else np.zeros(0)
        self.time = 0.0
        from fmpy.fmi1 import FMICallException
        self.FailedCall = FMICallException  # fmpy raises it for a status worse than warning
        try:
            self._initialise(start)
        except FMICallException as error:
            raise self.failure(error, "initialising it") from None

    def failure(self, error, what: str) -> FmuError:
        """A failed FMI call as an :class:`FmuError` naming the FMU, the call, its status and the time."""
        return FmuError(f"FMU {self.path.name}: {error.function} failed with status {error.status} "
                        f"({_STATUS.get(error.status, 'unknown')}) while {what} at t = {self.time:.9g} s")

    def _real_calls(self, set_name: str, get_name: str) -> None:
        """The FMU's own set and get of its real variables, called on the preallocated arrays (``set_inputs`` and
        ``get_outputs`` check the status they return): bare handles on the library's functions (``_bare``), their
        arguments built once as the C types FMI declares (the instance pointer, the value references, ``size_t``
        counts, the values)."""
        n_u, n_y = len(self._u_view), len(self._y_view)
        self._set, self._get = _bare(self.fmu.dll, set_name), _bare(self.fmu.dll, get_name)
        extra = self.version == "3"  # FMI 3.0 takes the number of values too
        self._instance = ctypes.c_void_p(self.fmu.component)
        n_u_arg, n_y_arg = ctypes.c_size_t(n_u), ctypes.c_size_t(n_y)
        self._set_arguments = (self._instance, self._inputs, n_u_arg, self._u) + ((n_u_arg,) if extra else ())
        self._get_arguments = (self._instance, self._outputs, n_y_arg, self._y) + ((n_y_arg,) if extra else ())

    def _discrete(self, names: tuple[str, ...], types: dict[str, str], verb: str) -> list[tuple]:
        """(positions, value references, fmpy's setter or getter, Boolean?) of the Integer and Boolean variables
        among ``names``, one entry per FMI type."""
        found = []
        for fmi_type, (kind, function) in DISCRETE_TYPES.items():
            positions = [i for i, n in enumerate(names) if types[n] == fmi_type]
            if positions:
                call = getattr(self.fmu, f"{verb}{function}", None)  # setInteger (FMI 2.0), setInt32 (3.0), …
                if call is None:
                    raise FmuError(f"FMU {self.path.name}: its {fmi_type} variables cannot be exchanged here")
                found.append((positions, [self.references[names[i]] for i in positions], call, kind == "Boolean"))
        return found

    def set_inputs(self, u: np.ndarray) -> None:
        if self._discrete_u:
            for positions, references, setter, boolean in self._discrete_u:  # Integer: nearest; Boolean: not 0
                values = u[positions]
                setter(references, [bool(v != 0.0) for v in values] if boolean else [int(round(v)) for v in values])
            u = u[self._real_u]
        if len(self._u_view):
            self._u_view[:] = u
            status = self._set(*self._set_arguments)
            if status > _WARNING:
                raise self.FailedCall(function=self._set.__name__, status=status)

    def get_outputs(self) -> np.ndarray:
        if len(self._y_view):
            status = self._get(*self._get_arguments)
            if status > _WARNING:
                raise self.FailedCall(function=self._get.__name__, status=status)
        if not self._discrete_y:
            return self._y_view.copy()
        y = np.empty(self._n_outputs)
        y[self._real_y] = self._y_view
        for positions, references, getter, _ in self._discrete_y:
            y[positions] = np.array(getter(references), dtype=np.float64)
        return y

    def save_state(self) -> bytes | object:
        """The FMU state: serialised bytes where the FMU can serialise it, else the FMU's own handle."""
        try:
            state = self.fmu.getFMUState()
            if not self._serialise:
                return _Handle(self.fmu, state)
            data = self._serialize(state)
            self.fmu.freeFMUState(state)
            return data
        except self.FailedCall as error:
            raise self.failure(error, "saving its state") from None

    def restore_state(self, state) -> None:
        try:
            if isinstance(state, _Handle):
                self.fmu.setFMUState(state.state)
            else:
                handle = self._deserialize(state)
                self.fmu.setFMUState(handle)
                self.fmu.freeFMUState(handle)
        except self.FailedCall as error:
            raise self.failure(error, "restoring its state") from None


class FmuCoSimulation(_FmuInstance):
    """An FMU advancing itself with ``doStep``. Its outputs right after a step whose inputs are the ones they are
    read with (a zero-order input polynomial: always) are read without setting the inputs again, as libcosim
    reads them: an FMU's input keeps the value last set until it is set again."""

    _stepped_with: list[float] | None = None  # the real inputs of the last doStep, until the outputs are read

    def _instantiate(self, model, description: ComponentDescription, instance_name: str):
        if self.version == "2":
            from fmpy.fmi2 import FMU2Slave as Slave
        else:
            from fmpy.fmi3 import FMU3Slave as Slave
        fmu = Slave(guid=model.guid, unzipDirectory=self.directory,
                    modelIdentifier=model.coSimulation.modelIdentifier, instanceName=instance_name)
        weakref.finalize(self, fmu.freeInstance)
        fmu.instantiate()
        self._serialise = bool(model.coSimulation.canSerializeFMUstate)
        return fmu

    def _initialise(self, start: dict[str, float]) -> None:
        fmu = self.fmu
        if self.version == "2":
            self._real_calls("fmi2SetReal", "fmi2GetReal")
            self._step = _bare(fmu.dll, "fmi2DoStep")  # called as the others, on the status it returns
            self._serialize, self._deserialize = fmu.serializeFMUstate, fmu.deSerializeFMUstate
            fmu.setupExperiment(startTime=0.0)
            _set_start(fmu.setReal, self.references, start)
        else:
            self._real_calls("fmi3SetFloat64", "fmi3GetFloat64")
            self._step = fmu.doStep  # fmpy's, which hands back the flags fmi3DoStep writes
            self._serialize, self._deserialize = fmu.serializeFMUState, fmu.deserializeFMUState
            _set_start(fmu.setFloat64, self.references, start)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()

    def initial_state(self) -> np.ndarray:
        return np.zeros(0)

    def do_step(self, t: float, h: float, u: np.ndarray) -> None:
        self.time = t
        try:
            self.set_inputs(u)
            self._stepped_with = None if self._discrete_u else u.tolist()
            if self.version == "2":  # 0: no fmi2SetFMUstate to an earlier time promised (zencosim may roll back)
                status = self._step(self._instance, ctypes.c_double(t), ctypes.c_double(h), FMI2_FALSE)
                if status > _WARNING:
                    raise self.FailedCall(function="fmi2DoStep", status=status)
                return
            result = self._step(t, h, False)
        except self.FailedCall as error:
            raise self.failure(error, "doStep") from None
        if result[1]:  # terminateSimulation
            raise self.asked_to_terminate(t)

    def asked_to_terminate(self, t: float) -> FmuError:
        """The FMU's ``fmi3DoStep`` at ``t`` [s] set terminateSimulation."""
        return FmuError(f"FMU {self.path.name}: asked to terminate the simulation at t = {t:.9g} s")

    def step_text(self, prefix: str, start_ns: str, micro_steps: int, h_ns: int) -> StepText | None:
        """One communication step of ``micro_steps`` micro-steps of ``h_ns`` with zero-order inputs as statements
        (``subsystems.subsystem.Subsystem.step_text``; ``start_ns``: the text of the step's start [ns], an int): the
        calls ``do_step`` and ``outputs`` make, with the same arguments — per micro-step the inputs set, then
        ``fmi2DoStep`` (``fmi3DoStep``) at ``t = (start + j h) × 1e-9`` s, and the outputs read at the end without
        setting the same inputs again — each status checked as they check it, a failure raised as the same
        :class:`FmuError`.
        Those calls are one call of ``fmi2_steps_run`` or ``fmi3_steps_run`` where they could be compiled
        (``fmi_steps``), else, for FMI 2.0, a ctypes call each. Real inputs and outputs only; else None, and so for
        FMI 3.0 without the compiled function."""
        if self._discrete_u or self._discrete_y:
            return None
        p, n_u, n_y = prefix, len(self._u_view), len(self._y_view)
        inputs, outputs = tuple(f"{p}c{i}" for i in range(n_u)), tuple(f"{p}y{i}" for i in range(n_y))

        run_steps = steps_function(self.version)
        if run_steps is not None:
            return self._steps_text(p, start_ns, micro_steps, h_ns, inputs, outputs, run_steps)
        if self.version != "2":
            return None
        lines = []
        for j in range(micro_steps):
            t = f"({start_ns} + {j * h_ns}) * 1e-9"
            if n_u:
                lines += [f"{p}u[{i}] = {name}" for i, name in enumerate(inputs)]
                lines += [f"{p}status = {p}set_real(*{p}set_arguments)",
                          f"if {p}status > {_WARNING}: raise {p}failed({self._set.__name__!r}, {p}status, {t}, "
                          "'doStep')"]
            lines += [f"{p}time.value = {t}", f"{p}status = {p}do_step({p}instance, {p}time, {p}h, {p}false)",
                      f"if {p}status > {_WARNING}: raise {p}failed('fmi2DoStep', {p}status, {t}, 'doStep')"]
        if n_y:
            t = f"({start_ns} + {micro_steps * h_ns}) * 1e-9"
            lines += [f"{p}status = {p}get_real(*{p}get_arguments)",
                      (f"if {p}status > {_WARNING}: raise {p}failed({self._get.__name__!r}, {p}status, {t}, "
                       "'reading its outputs')"),
                      *(f"{name} = {p}y[{i}]" for i, name in enumerate(outputs))]

        namespace = {f"{p}u": self._u, f"{p}y": self._y, f"{p}set_real": self._set, f"{p}get_real": self._get,
                     f"{p}set_arguments": self._set_arguments, f"{p}get_arguments": self._get_arguments,
                     f"{p}do_step": self._step, f"{p}instance": self._instance, f"{p}time": ctypes.c_double(),
                     f"{p}h": ctypes.c_double(h_ns * 1e-9), f"{p}false": FMI2_FALSE, f"{p}failed": self._failed_at}
        return StepText(tuple(lines), (), inputs, (), inputs, outputs, namespace)

    def _failed_at(self, function: str, status: int, t: float, what: str) -> FmuError:
        """The failure of FMI call ``function`` with ``status`` at ``t`` [s] while ``what``, as :meth:`failure` names
        it (the FMU's time set to ``t``)."""
        self.time = t
        return self.failure(self.FailedCall(function=function, status=status), what)

    def _steps_text(self, p: str, start_ns: str, micro_steps: int, h_ns: int, inputs: tuple[str, ...],
                    outputs: tuple[str, ...], run_steps) -> StepText:
        """``step_text``'s statements with the step's FMI calls as one call of ``run_steps`` (``fmi_steps``), which
        makes the same calls with the same arguments from :class:`FmiSteps`; a failure raised as ``do_step`` and
        ``outputs`` raise it. The same call is the text's ``native`` step, for a loop that runs in C."""
        address = ctypes.addressof
        do_step = f"fmi{self.version}DoStep"

        def function(handle) -> int:
            return ctypes.cast(handle, ctypes.c_void_p).value
        steps = FmiSteps(set=function(self._set), do_step=function(self.fmu.dll[do_step]), get=function(self._get),
                         instance=self._instance.value, inputs=address(self._inputs), n_inputs=len(inputs),
                         u=address(self._u), outputs=address(self._outputs), n_outputs=len(outputs),
                         y=address(self._y), h_ns=h_ns, h=h_ns * 1e-9, micro_steps=micro_steps)

        def step_failure(status: int) -> FmuError:
            call, t = steps.failed_call, steps.failed_time
            if status == TERMINATE:
                self.time = t
                return self.asked_to_terminate(t)
            return self._failed_at((self._set.__name__, do_step, self._get.__name__)[call], status, t,
                                   "reading its outputs" if call == 2 else "doStep")

        lines = [f"{p}u[{i}] = {name}" for i, name in enumerate(inputs)]
        lines += [f"{p}start.value = {start_ns}", f"{p}status = {p}run_steps({p}steps, {p}start)",
                  f"if {p}status: raise {p}step_failure({p}status)"]
        lines += [f"{name} = {p}y[{i}]" for i, name in enumerate(outputs)]
        namespace = {f"{p}u": self._u, f"{p}y": self._y, f"{p}run_steps": run_steps, f"{p}steps": ctypes.pointer(steps),
                     f"{p}start": ctypes.c_longlong(), f"{p}step_failure": step_failure}
        return StepText(tuple(lines), (), inputs, (), inputs, outputs, namespace,
                        NativeStep(run_steps, steps, self._u, self._y, step_failure))

    def outputs(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        self.time = t
        try:
            if self._stepped_with is None or u.tolist() != self._stepped_with:
                self.set_inputs(u)
            self._stepped_with = None
            return self.get_outputs()
        except self.FailedCall as error:
            raise self.failure(error, "reading its outputs") from None

    def restore_state(self, state) -> None:
        self._stepped_with = None  # the restored FMU holds the inputs of its saved state
        super().restore_state(state)


class FmuModelExchange(_FmuInstance):
    """An FMI 2.0 FMU for Model Exchange: zencosim's integrator advances its continuous states."""

    def _instantiate(self, model, description: ComponentDescription, instance_name: str):
        from fmpy.fmi2 import FMU2Model
        fmu = FMU2Model(guid=model.guid, unzipDirectory=self.directory,
                        modelIdentifier=model.modelExchange.modelIdentifier, instanceName=instance_name)
        weakref.finalize(self, fmu.freeInstance)
        fmu.instantiate()
        self._serialise = True
        self.n_states = len(model.derivatives)
        return fmu

    def _initialise(self, start: dict[str, float]) -> None:
        fmu = self.fmu
        self._real_calls("fmi2SetReal", "fmi2GetReal")
        fmu.setupExperiment(startTime=0.0)
        _set_start(fmu.setReal, self.references, start)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        while fmu.newDiscreteStates()[0]:  # newDiscreteStatesNeeded
            pass
        fmu.enterContinuousTimeMode()
        self._x = (ctypes.c_double * self.n_states)()
        self._dx = (ctypes.c_double * self.n_states)()
        self._x_view, self._dx_view = np.ctypeslib.as_array(self._x), np.ctypeslib.as_array(self._dx)
        fmu.getContinuousStates(self._x, self.n_states)
        self._z0 = self._x_view.copy()

    def initial_state(self) -> np.ndarray:
        return self._z0.copy()

    def _at(self, t: float, z: np.ndarray, u: np.ndarray) -> None:
        self.time = t
        fmu = self.fmu
        fmu.fmi2SetTime(fmu.component, t)
        self._x_view[:] = z
        fmu.fmi2SetContinuousStates(fmu.component, self._x, self.n_states)
        self.set_inputs(u)

    def derivative(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        try:
            self._at(t, z, u)
            self.fmu.fmi2GetDerivatives(self.fmu.component, self._dx, self.n_states)
            return self._dx_view.copy()
        except self.FailedCall as error:
            raise self.failure(error, "computing its derivatives") from None

    def outputs(self, t: float, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        try:
            self._at(t, z, u)
            return self.get_outputs()
        except self.FailedCall as error:
            raise self.failure(error, "reading its outputs") from None


def _set_start(setter, references: dict[str, int], start: dict[str, float]) -> None:
    """Set the real start values (the scene's start table takes real variables: ``read_start``)."""
    if start:
        setter([references[name] for name in start], [float(value) for value in start.values()])


class _Handle:
    """An FMU state that cannot be serialised: the FMU's handle, freed when no saved state holds it."""

    def __init__(self, fmu, state) -> None:
        self.state = state
        weakref.finalize(self, fmu.freeFMUState, state)


_STATUS = {1: "warning", 2: "discard", 3: "error", 4: "fatal", 5: "pending"}


def open_fmu(path: Path, description: ComponentDescription, start: dict[str, float], inputs: tuple[str, ...],
             outputs: tuple[str, ...], instance_name: str):
    """An instance of the FMU for one subsystem (see :class:`~.component.Instance`)."""
    cls = FmuCoSimulation if description.interface == "co-simulation" else FmuModelExchange
    return cls(path, description, start, inputs, outputs, instance_name)


def _bare(library: ctypes.CDLL, name: str):
    """A handle on ``name`` in the FMU's library without fmpy's argument types (``library[name]`` makes a new one;
    ``getattr`` returns fmpy's): ctypes then passes arguments that are already of the C types as they are, where
    converting them through the declared types cost about 3,500 instructions a call (valgrind; a call is 9,000);
    it returns the FMI status, an int."""
    function = library[name]
    function.restype = ctypes.c_int
    return function
