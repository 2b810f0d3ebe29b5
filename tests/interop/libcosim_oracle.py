"""libcosim, the OSP reference co-simulation engine, as an oracle: run an OSP system with libcosimpy and
return the trajectories it computed, sample for sample.

``run_osp(path, duration, [("mass2", "x2"), ...])`` loads ``path`` (an ``OspSystemStructure.xml`` with its
FMUs) with ``CosimExecution.from_osp_config_file`` (an SSP ``.ssd`` file or ``.ssp`` archive with libcosim's
SSP loader, ``CosimExecution.from_ssp_file``, which applies a connection's ``ssc:LinearTransformation`` and
converts no units), observes the requested variables with a time-series
observer from the start, simulates to ``duration`` and returns a :class:`LibcosimRun`: the times [s] and
step numbers of every sample and the values of each variable, numpy arrays of one length. libcosim's
time-series observer takes a sample when the simulation is initialised (step 0, t = 0) and after every
step a simulator completes (with a stepSize that is k base steps, every k-th step): every base step for
the systems here.

libcosimpy facts this relies on (libcosimpy 0.0.6, its bundled libcosimc):

* ``CosimExecution.from_osp_config_file(path)`` validates the file against libcosim's schema (namespace
  ``http://opensimulationplatform.com/MSMI/OSPSystemStructure``, ``version="0.1"``) and *asserts* on
  failure (``AssertionError`` carrying ``cosim_last_error_message``); ``step``/``simulate_until`` return
  False on failure. The first step initialises the simulation: until then nothing has been observed.
* ``slave_infos()`` (name, index) and ``slave_variables(index)`` (name, value reference) name things;
  simulator indices are not in document order.
* ``CosimObserver.create_time_series()`` keeps only the newest 10 000 samples of each variable (measured:
  after 10 000 steps, step 0 is gone); ``create_time_series(buffer_size=N)`` keeps N, so the oracle asks
  for 2**40. ``start_time_series`` must be called before the first step for step 0 to be kept.
* ``CosimObserver.time_series_real_samples`` trims its answer by counting the zeros in the step-number
  array, which drops a real sample whenever step 0 is among those asked for; so the samples are read here
  with libcosimc's ``cosim_observer_slave_get_real_samples`` itself, whose return value is the count.
* Execution and observers are C objects freed by ``__del__``; :func:`run_osp` frees them itself, on
  success and on failure, and leaves ``__del__`` nothing to do.
"""
from __future__ import annotations

import ctypes
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

CHUNK = 4096  # samples read per call
BUFFER = 1 << 40  # samples a time-series observer keeps per variable (a std::map: nothing is reserved)


class LibcosimError(RuntimeError):
    """libcosim could not load or run the system; the message holds libcosim's last error."""


@dataclass
class LibcosimRun:
    """What libcosim computed: one sample per observed step."""

    time: np.ndarray  # [s], float64: libcosim's integer nanoseconds * 1e-9
    steps: np.ndarray  # step numbers, int64
    values: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)  # (simulator, variable) -> values

    def __getitem__(self, key: tuple[str, str]) -> np.ndarray:
        return self.values[key]


def _libcosimc():
    from libcosimpy._internal import libcosimc

    return libcosimc()


def _last_error() -> str:
    from libcosimpy._internal import get_last_error_message

    try:
        return get_last_error_message()
    except Exception:  # noqa: BLE001 (no message is no reason to hide the failure)
        return "(libcosim gave no message)"


def _real_samples(observer, simulator: int, reference: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every real sample of one variable: (values, step numbers, times in ns), read in chunks."""
    function = _libcosimc().cosim_observer_slave_get_real_samples
    function.restype = ctypes.c_int64
    function.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint32, ctypes.c_int64, ctypes.c_size_t,
                         ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int64),
                         ctypes.POINTER(ctypes.c_int64)]
    values, steps, times = [], [], []
    from_step = 0
    while True:
        chunk_values = np.empty(CHUNK, dtype=np.float64)
        chunk_steps = np.empty(CHUNK, dtype=np.int64)
        chunk_times = np.empty(CHUNK, dtype=np.int64)
        pointer = ctypes.cast(observer.ptr(), ctypes.c_void_p)
        count = function(pointer, simulator, reference, from_step, CHUNK,
                         chunk_values.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                         chunk_steps.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                         chunk_times.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)))
        if count < 0:
            raise LibcosimError(f"reading the samples of simulator {simulator}, value reference {reference} "
                                f"failed: {_last_error()}")
        values.append(chunk_values[:count])
        steps.append(chunk_steps[:count])
        times.append(chunk_times[:count])
        if count < CHUNK:
            break
        from_step = int(chunk_steps[count - 1]) + 1
    return np.concatenate(values), np.concatenate(steps), np.concatenate(times)


def _free(obj, owner: str) -> None:
    """Free a libcosimpy C object now, and leave its ``__del__`` nothing to free later."""
    if obj is None:
        return
    attribute = f"_{owner}__ptr"  # libcosimpy keeps the C pointer in a name-mangled attribute
    if getattr(obj, attribute, None) is None:
        return
    try:
        obj.__del__()
    finally:
        setattr(obj, attribute, None)


def run_osp(system: str | Path, duration: float, variables: Iterable[tuple[str, str]],
            log_level: str = "ERROR") -> LibcosimRun:
    """Run the OSP system ``system`` with libcosim from t = 0 to ``duration`` [s] and return the samples of
    ``variables`` ((simulator name, variable name) pairs, Real variables) at every step. Raises
    :class:`LibcosimError` naming what failed; the execution and its observer are freed in every case."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(getattr(CosimLogLevel, log_level))
    wanted = list(variables)
    end_ns = round(duration * 1e9)
    execution = observer = None
    try:
        ssp = Path(system).suffix.lower() in (".ssd", ".ssp")
        try:
            execution = (CosimExecution.from_ssp_file if ssp else CosimExecution.from_osp_config_file)(str(system))
        except AssertionError as error:
            raise LibcosimError(f"libcosim cannot load {system}: {error}") from None
        observer = CosimObserver.create_time_series(buffer_size=BUFFER)
        if not execution.add_observer(observer):
            raise LibcosimError(f"adding a time-series observer failed: {_last_error()}")
        simulators = {info.name.decode(): info.index for info in execution.slave_infos()}
        observed = {}
        for simulator, name in wanted:
            if simulator not in simulators:
                raise LibcosimError(f"{system}: no simulator {simulator!r}; it has {', '.join(sorted(simulators))}")
            index = simulators[simulator]
            references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
            if name not in references:
                raise LibcosimError(f"{system}: simulator {simulator!r} has no variable {name!r}")
            if not observer.start_time_series(index, references[name], CosimVariableType.REAL):
                raise LibcosimError(f"observing {simulator}.{name} failed: {_last_error()}")
            observed[(simulator, name)] = (index, references[name])
        if not execution.simulate_until(end_ns):
            raise LibcosimError(f"libcosim failed running {system}: {_last_error()}")
        run = None
        for key, (index, reference) in observed.items():
            values, steps, times = _real_samples(observer, index, reference)
            if run is None:
                run = LibcosimRun(times * 1e-9, steps)
            elif not np.array_equal(steps, run.steps):
                raise LibcosimError(f"{key[0]}.{key[1]} was sampled at other steps than {wanted[0]}; "
                                    "observe simulators of one step size together")
            run.values[key] = values
        return run if run is not None else LibcosimRun(np.empty(0), np.empty(0, dtype=np.int64))
    finally:
        _free(execution, "CosimExecution")
        _free(observer, "CosimObserver")
