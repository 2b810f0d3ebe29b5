"""A Jacobi master for the peer pair written out in Python over fmpy, to tell where two engines differ.

libcosim's fixed-step algorithm (``src/cosim/algorithm/fixed_step_algorithm.cpp``) and zencosim's ZOH
Jacobi step exchange values at the same instants: every FMU steps from t_k with the inputs transferred
at t_k, and the outputs read after ``doStep`` (fc, a direct-feedthrough output, with the inputs of t_k
still set) are transferred for the next step. What differs is the step size each hands ``fmi2DoStep``:

* libcosim: ``to_double_duration(deltaT, currentT)`` = t_{k+1} - t_k, each time point an integer count of
  nanoseconds divided by 1e9: 0.001 to within a few ULPs, varying with k
  (``src/cosim/fmi/v2/fmu.cpp``, ``slave_instance::do_step``);
* zencosim: the micro-step in nanoseconds times 1e-9, exactly the double 0.001 at every step.

:func:`run_pair` runs that master with either step size; with ``step="libcosim"`` it reproduces libcosim
bit for bit and with ``step="zencosim"`` it reproduces zencosim bit for bit (the tests say whether it
does), so the difference between the two engines is the rounding of the step size alone.
"""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from tests.interop.peer_pair import MASS1_START, MASS2_START, MODELS

NS = 1_000_000_000


def _slave(fmu: Path, name: str, unpacked: Path):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    description = read_model_description(str(fmu), validate=False)
    slave = FMU2Slave(guid=description.guid, unzipDirectory=str(extract(str(fmu), str(unpacked / name))),
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    references = {v.name: v.valueReference for v in description.modelVariables}
    return slave, references


def run_pair(directory: Path, steps: int, base_step_ns: int = 1_000_000, step: str = "libcosim") -> dict:
    """Run ``mass1.fmu`` and ``mass2.fmu`` of ``directory`` for ``steps`` base steps; return the samples
    (step 0 to ``steps``) of ``x2``, ``v2`` and ``fc`` and the times [s] as numpy arrays."""
    if step not in ("libcosim", "zencosim"):
        raise ValueError(f"step must be 'libcosim' or 'zencosim', not {step!r}")
    unpacked = Path(tempfile.mkdtemp(prefix="peer-replica-"))
    slaves = []
    try:
        mass1, r1 = _slave(directory / "mass1.fmu", "mass1", unpacked)
        slaves.append(mass1)
        mass2, r2 = _slave(directory / "mass2.fmu", "mass2", unpacked)
        slaves.append(mass2)
        assert {v.name for v in MODELS["mass1"]} == set(r1) and {v.name for v in MODELS["mass2"]} == set(r2)
        out1, out2 = [r1["x1"], r1["v1"], r1["fc"]], [r2["x2"], r2["v2"]]
        in1, in2 = [r1["x2_in"], r1["v2_in"]], [r2["fc_in"]]
        for slave, references, start in ((mass1, r1, MASS1_START), (mass2, r2, MASS2_START)):
            slave.instantiate()
            slave.setReal([references[n] for n in start], list(start.values()))
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()

        def transfer():
            _, _, fc = mass1.getReal(out1)
            x2, v2 = mass2.getReal(out2)
            mass1.setReal(in1, [x2, v2])
            mass2.setReal(in2, [fc])
            return x2, v2, fc

        for _ in range(2):  # libcosim: as many iterations as simulators, to propagate the initial values
            transfer()
        for slave in slaves:
            slave.exitInitializationMode()
        samples = [transfer()]
        for k in range(steps):
            t0_ns, t1_ns = k * base_step_ns, (k + 1) * base_step_ns
            h = t1_ns / NS - t0_ns / NS if step == "libcosim" else base_step_ns * 1e-9
            for slave in slaves:
                slave.doStep(t0_ns / NS, h)
            samples.append(transfer())
        values = np.array(samples)
        return {"time": np.arange(steps + 1) * base_step_ns / NS, "x2": values[:, 0], "v2": values[:, 1],
                "fc": values[:, 2]}
    finally:
        for slave in slaves:
            try:
                slave.terminate()
            except Exception:  # noqa: BLE001 (an instance that never initialised cannot terminate)
                pass
            slave.freeInstance()
        shutil.rmtree(unpacked, ignore_errors=True)
