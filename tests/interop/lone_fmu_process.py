"""Run one FMU alone in a fresh process, with one tool, and save every output: for FMUs made with pythonfmu.

``python -m tests.interop.lone_fmu_process TOOL FMU INPUTS.csv OUT.npz`` (from the repository root), TOOL one of

* ``fmpy``: ``fmpy.simulate_fmu`` with its default experiment and the input table (what the FMU's authors use);
* ``zencosim``: ``zencosim.run(zencosim.load_scene(FMU, {"input": INPUTS.csv}))``, in process;
* ``replica-fmpy`` / ``replica-zencosim``: the same fixed-step loop written out over fmpy's ``FMU2Slave``, each
  ``doStep`` handed the communication point and step the named tool hands it: fmpy ``t_n = n h`` and
  ``t_{n+1} - t_n``, zencosim ``t_n = n h_ns 1e-9`` and ``h_ns 1e-9``; inputs set before each ``doStep`` at
  ``t_n`` (``Input.interpolate(t_n, after_event=True)``, as both tools take them), outputs read after it.

OUT.npz holds ``time`` and one array per output variable. Why a process of its own: a pythonfmu FMU runs its
model in the interpreter of the process that loads it, so two of them whose resources hold different versions
of one package (crane-fmu's FMUs bundle different ``component_model``s) share whichever ``sys.modules`` got
first, and fmpy deletes the unpacked resources a module may still load from; the second FMU then fails to
instantiate (measured: "No module named 'component_model.utils'").
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np


def _outputs(fmu: Path) -> list[str]:
    from fmpy import read_model_description

    return [v.name for v in read_model_description(str(fmu), validate=False).modelVariables
            if v.causality == "output"]


def run_fmpy(fmu: Path, table: Path) -> dict[str, np.ndarray]:
    from fmpy import simulate_fmu
    from fmpy.util import read_csv

    result = simulate_fmu(str(fmu), input=read_csv(table))
    return {name: np.asarray(result[name]) for name in result.dtype.names}


def run_zencosim(fmu: Path, table: Path) -> dict[str, np.ndarray]:
    import zencosim

    result = zencosim.run(zencosim.load_scene(str(fmu), {"input": str(table)}))
    names = _outputs(fmu)
    out = {"time": result.signal(names[0]).time}
    out |= {name: result.signal(name).values for name in names}
    return out


def run_replica(fmu: Path, table: Path, step: str) -> dict[str, np.ndarray]:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.simulation import Input
    from fmpy.util import read_csv

    description = read_model_description(str(fmu), validate=False)
    experiment = description.defaultExperiment
    h, stop = float(experiment.stepSize), float(experiment.stopTime)
    h_ns, steps = round(h * 1e9), round(stop / h)
    references = {v.name: v.valueReference for v in description.modelVariables}
    names = _outputs(fmu)
    data = read_csv(table)
    inputs = list(data.dtype.names[1:])
    values = np.array([data[name] for name in inputs], dtype=np.float64)
    unpacked = Path(tempfile.mkdtemp(prefix="lone-replica-"))
    slave = FMU2Slave(guid=description.guid, unzipDirectory=str(extract(str(fmu), str(unpacked))),
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="replica")
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        outs = [references[n] for n in names]
        ins = [references[n] for n in inputs]
        samples, times = [slave.getReal(outs)], [0.0]
        for n in range(steps):
            if step == "fmpy":
                t, size = n * h, (n + 1) * h - n * h
            else:
                t, size = n * h_ns * 1e-9, h_ns * 1e-9
            u, _ = Input.interpolate(t, data["time"], values, after_event=True)
            slave.setReal(ins, [float(v) for v in u])
            slave.doStep(t, size)
            samples.append(slave.getReal(outs))
            times.append((n + 1) * h if step == "fmpy" else (n + 1) * h_ns * 1e-9)
        array = np.array(samples)
        return {"time": np.array(times)} | {name: array[:, i] for i, name in enumerate(names)}
    finally:
        try:
            slave.terminate()
        finally:
            slave.freeInstance()
            shutil.rmtree(unpacked, ignore_errors=True)


def main(argv: list[str]) -> int:
    tool, fmu, table, out = argv
    runners = {"fmpy": run_fmpy, "zencosim": run_zencosim,
               "replica-fmpy": lambda f, t: run_replica(f, t, "fmpy"),
               "replica-zencosim": lambda f, t: run_replica(f, t, "zencosim")}
    np.savez(out, **runners[tool](Path(fmu), Path(table)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
