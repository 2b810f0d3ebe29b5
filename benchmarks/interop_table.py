"""zencosim against libcosim (and FMPy) on the same artifacts: a markdown table of what each tool ran and
the largest difference between their trajectories.

    python benchmarks/interop_table.py                      # the table on stdout
    python benchmarks/interop_table.py --zenoh --out table.md

Needs gcc, fmpy and libcosimpy (``pip install -e '.[test]'``). The artifacts are built in a temporary
folder: the peer pair of tests/interop (paper 000's two_mass_damped as two FMUs written for the tests) in
five OSP system structures, its signal, transformation and unit variants (tests/interop/peer_systems.py: OSP
and SSP files), its rotational, electrical and hydraulic builds (tests/interop/test_domains_osp.py), and the FMU
scenes of ``zencosim examples`` written as OSP files. "largest
difference" is max |a - b| / max |b| over the coupling signals (x2, v2 and the force), b the run named in
"against"; NRMS is that of x2 against the analytic solution (paper 000 Eq. 42) where the system is
two_mass_damped. docs/interop.md shows a run of it and explains the numbers.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # the oracle and the peer pair live with the tests

import zencosim  # noqa: E402
from tests.interop.libcosim_oracle import run_osp as _run_osp  # noqa: E402
from tests.interop.measures import analytic_x2, largest_difference, nrms  # noqa: E402
from tests.interop.peer_pair import END_TIME, MASS2_START, OSP_NAMESPACE, SYSTEMS, write_system  # noqa: E402
from tests.interop.replica import run_pair  # noqa: E402
from tests.interop.scene_osp import write_osp  # noqa: E402

PEER = {"x2": ("mass2", "x2"), "v2": ("mass2", "v2"), "fc": ("mass1", "fc")}
EXAMPLES = ("two_mass_damped_fmu", "double_oscillator_fmu")


def run_osp(path: Path, duration: float, variables) -> object:
    """libcosim's run, its log kept off stdout (libcosim logs to stdout; a failure still raises with its message)."""
    return _run_osp(path, duration, variables, log_level="FATAL")


class Table:
    def __init__(self) -> None:
        self.rows: list[tuple[str, ...]] = []

    def add(self, artifact: str, tool: str, ran: str, error: float | None, difference: float | str | None,
            against: str = "") -> None:
        nrms_text = "" if error is None else f"{error:.6f}"
        if difference is None:
            difference_text = ""
        elif isinstance(difference, str):
            difference_text = difference
        else:
            difference_text = "0 (bit for bit)" if difference == 0.0 else f"{difference:.1e}"
        self.rows.append((artifact, tool, ran, nrms_text, difference_text, against))
        print(" | ".join(self.rows[-1]), file=sys.stderr, flush=True)

    def markdown(self) -> str:
        header = ("artifact", "tool", "what ran", "NRMS x2", "largest difference", "against")
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in self.rows]
        return "\n".join(lines) + "\n"


def difference(ours: dict, theirs: dict) -> float:
    return max(largest_difference(ours[name], theirs[name]) for name in theirs)


SIGNALS = {"x2": "mass2_x2", "v2": "mass2_v2", "fc": "mass1_fc"}  # the peer pair's signal couplings


def zencosim_run(path: Path, bus: str = "inproc", overrides: dict | None = None):
    scene = zencosim.load_scene(path, overrides or {})
    result = zencosim.run(scene, bus)
    if all(coupling.kind == "signal" for coupling in scene.couplings.values()):  # no bond: signals by name
        names = {k: n for k, n in SIGNALS.items() if n in scene.couplings}
        names |= {k: k for k in ("x2", "v2") if k not in names}  # published by a subsystem with outputs = "all"
        return result, {k: result.signal(n).values for k, n in names.items()}
    (coupling,) = scene.couplings
    return result, {"x2": result.signal(f"{coupling}.x").values, "v2": result.signal(f"{coupling}.v").values,
                    "fc": result.signal(f"{coupling}.f").values}


def signals_and_ssp(table: Table, root: Path, reference: np.ndarray) -> None:
    """Signal couplings and a simulator alone (OSP), a force transformation and a unit conversion (SSP)."""
    from tests.interop.peer_systems import alone, oneway, write_ssd

    for name, path, overrides in (("oneway", oneway(root / "oneway"), {"subsystems.mass2.outputs": "all"}),
                                  ("alone", alone(root / "alone"), {})):
        keys = dict(PEER) if name == "oneway" else {k: PEER[k] for k in ("x2", "v2")}
        run = run_osp(path, END_TIME, keys.values())
        theirs = {signal: run[key] for signal, key in keys.items()}
        artifact = f"peer OSP `{name}`"
        table.add(artifact, "libcosim", "the OSP file", None, None)
        _, ours = zencosim_run(path, overrides=overrides)
        table.add(artifact, "zencosim", "the OSP file, in process", None, difference(ours, theirs), "libcosim")
    variants = {v: write_ssd(root / f"ssp_{v}", v) for v in ("plain", "own", "mm", "mm_transformed")}
    plain_run = run_osp(variants["plain"], END_TIME, PEER.values())
    plain = {signal: plain_run[key] for signal, key in PEER.items()}
    table.add("peer SSP `plain`", "libcosim", "the SSP file", nrms(plain["x2"], reference), None)
    _, ours = zencosim_run(variants["plain"])
    table.add("peer SSP `plain`", "zencosim", "the SSP file, in process", nrms(ours["x2"], reference),
              difference(ours, plain), "libcosim")
    run = run_osp(variants["own"], END_TIME, [PEER["x2"], PEER["v2"]])
    theirs = {"x2": run[PEER["x2"]], "v2": run[PEER["v2"]]}
    table.add("peer SSP `own` (factor -1)", "libcosim", "the SSP file", nrms(theirs["x2"], reference),
              difference(theirs, {k: plain[k] for k in theirs}), "libcosim, SSP `plain`")
    _, own = zencosim_run(variants["own"])
    table.add("peer SSP `own` (factor -1)", "zencosim", "the SSP file, in process", nrms(own["x2"], reference),
              difference({k: own[k] for k in theirs}, theirs), "libcosim")
    for variant in ("plain", "own"):
        table.add(f"peer SSP `{variant}`", "FMPy simulate_ssp", "the SSP file as an archive", None,
                  difference(fmpy_ssp(variants[variant]), {k: plain[k][1:] for k in ("x2",)}),
                  "libcosim, SSP `plain`, from step 1")
    run = run_osp(variants["mm_transformed"], END_TIME, PEER.values())
    theirs = {signal: run[key] for signal, key in PEER.items()}
    theirs["x2"] = theirs["x2"] * 1e-3  # mm
    table.add("peer SSP `mm_transformed`", "libcosim", "the SSP file", nrms(theirs["x2"], reference), None)
    _, mm = zencosim_run(variants["mm"])
    table.add("peer SSP `mm` (x2 in mm)", "zencosim", "the SSP file, in process", nrms(mm["x2"], reference),
              difference(mm, theirs), "libcosim, `mm_transformed`")


def domains(table: Table, root: Path, reference: np.ndarray) -> None:
    """The peer pair in rotational, electrical and hydraulic units (tests/interop/test_domains_osp.py): an
    AngularMechanicalPort bond with its angle, an ElectromagneticPort bond without charge (displacement = []),
    a hydraulic powerBond pair by units with its volume; a port of mixed domains, refused by zencosim."""
    from tests.interop.test_domains_osp import write_domain_system

    what = {"rotational": "AngularMechanicalPort + AngularDisplacement", "electrical": "ElectromagneticPort alone",
            "hydraulic": "powerBond Pa, m3/s + m3"}
    for domain, ran in what.items():
        path = write_domain_system(root / domain, domain)
        run = run_osp(path, END_TIME, PEER.values())
        keys = PEER if domain != "electrical" else {k: PEER[k] for k in ("v2", "fc")}  # no charge exchanged
        theirs = {signal: run[key] for signal, key in keys.items()}
        error = nrms(run[PEER["x2"]], reference) if domain != "electrical" else None
        artifact = f"peer {domain} ({ran})"
        table.add(artifact, "libcosim", "the OSP file", error, None)
        scene = zencosim.load_scene(path)
        result = zencosim.run(scene)
        (coupling,) = scene.couplings
        ours = {"v2": result.signal(f"{coupling}.v").values, "fc": result.signal(f"{coupling}.f").values}
        if "x2" in theirs:
            ours["x2"] = result.signal(f"{coupling}.x").values
        table.add(artifact, "zencosim", f"the OSP file, in process ({domain} bond)",
                  None if error is None else nrms(ours["x2"], reference), difference(ours, theirs), "libcosim")
    path = write_domain_system(root / "mixed", "rotational", models=("mass1", "mass2_rotational"))
    run_osp(path, END_TIME, PEER.values())
    table.add("peer mixed (N connected as a Torque)", "libcosim", "the OSP file", None, None)
    try:
        zencosim.load_scene(path)
        outcome = "ran (expected a refusal)"
    except zencosim.SceneError as error:
        outcome = f"refused: SceneError, {len(error.problems)} problems"
        print(error, file=sys.stderr)
    table.add("peer mixed (N connected as a Torque)", "zencosim", outcome, None, None)


def fmpy_ssp(ssd: Path) -> dict:
    """x2 from FMPy's ``simulate_ssp`` on the folder of ``ssd`` zipped (its start values as the one parameter
    set FMPy takes); sample k is after step k + 1."""
    import zipfile

    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    archive = ssd.parent.with_suffix(".ssp")
    with zipfile.ZipFile(archive, "w") as out:
        for file in ssd.parent.iterdir():
            out.write(file, file.name)
    parameters = ParameterSet(parameters=[])
    for component in read_ssd(str(archive)).system.elements:
        for parameter in component.parameterBindings[0].parameterValues[0].parameters:
            parameters.parameters.append(Parameter(name=f"{component.name}.{parameter.name}", type="Real",
                                                   value=parameter.value))
    result = simulate_ssp(str(archive), stop_time=END_TIME, step_size=0.001, parameter_set=parameters)
    return {"x2": np.asarray(result["mass2.x2"])[:len(result) - 1]}


def peer_pair(table: Table, root: Path, reference: np.ndarray, zenoh: bool) -> None:
    first = None
    for name in SYSTEMS:
        path = write_system(root / name, name)
        artifact = f"peer pair `{name}`"
        run = run_osp(path, END_TIME, PEER.values())
        theirs = {signal: run[key] for signal, key in PEER.items()}
        if first is None:
            first = theirs
            table.add(artifact, "libcosim", "the OSP file", nrms(theirs["x2"], reference), None)
        else:
            table.add(artifact, "libcosim", "the OSP file", nrms(theirs["x2"], reference), difference(theirs, first),
                      "libcosim, `plain`")
        try:
            result, ours = zencosim_run(path)
        except zencosim.SceneError as error:
            for problem in error.problems:
                print(f"{name}: zencosim refuses: {problem.key}: {problem.reason}", file=sys.stderr)
            table.add(artifact, "zencosim", f"refused: SceneError, {len(error.problems)} problems", None, None)
            continue
        table.add(artifact, "zencosim", "the OSP file, in process", nrms(ours["x2"], reference),
                  difference(ours, theirs), "libcosim")
        if zenoh and name == "plain":
            over_zenoh = zencosim.run(zencosim.load_scene(path), "zenoh")
            same = "equal digests" if over_zenoh.digest == result.digest else "DIGESTS DIFFER"
            table.add(artifact, "zencosim", "the OSP file over Zenoh", None, same, "zencosim in process")
        if name == "plain":
            replica = run_pair(path.parent, len(run.time) - 1, step="libcosim")
            table.add(artifact, "replica", "fmpy master, h = t_{k+1} - t_k", None,
                      difference({k: replica[k] for k in PEER}, theirs), "libcosim")
            replica = run_pair(path.parent, len(run.time) - 1, step="zencosim")
            table.add(artifact, "replica", "fmpy master, h = 0.001", None,
                      difference({k: replica[k] for k in PEER}, ours), "zencosim")


def examples(table: Table, root: Path, reference: np.ndarray) -> None:
    from zencosim.examples.write import write_examples

    write_examples(root)
    for name in EXAMPLES:
        osp = write_osp(root / f"{name}.toml", root / f"{name}_osp.xml")
        scene = zencosim.load_scene(osp)
        force_side, motion_side = list(scene.subsystems)
        run = run_osp(osp, END_TIME, [(motion_side, "x"), (motion_side, "v"), (force_side, "fc")])
        theirs = {"x2": run[(motion_side, "x")], "v2": run[(motion_side, "v")], "fc": run[(force_side, "fc")]}
        artifact = f"example `{name}`"
        error = (lambda x: nrms(x, reference)) if name == "two_mass_damped_fmu" else (lambda x: None)
        table.add(artifact, "libcosim", "its OSP file", error(theirs["x2"]), None)
        _, ours = zencosim_run(osp)
        table.add(artifact, "zencosim", "its OSP file, in process", error(ours["x2"]), difference(ours, theirs),
                  "libcosim")
        toml = zencosim.run(zencosim.load_scene(root / f"{name}.toml"))
        force = "fc" if name == "two_mass_damped_fmu" else "f"
        from_toml = {"x2": toml.signal("x2").values, "v2": toml.signal("v2").values,
                     "fc": toml.signal(force).values}
        table.add(artifact, "zencosim", "its TOML scene", error(from_toml["x2"]),
                  difference(from_toml, ours), "zencosim, OSP file")


def single_fmu(table: Table, root: Path) -> None:
    """mass2 alone (no force): FMPy's simulate_fmu against libcosim running a one-simulator OSP file."""
    from fmpy import simulate_fmu

    directory = root / "alone"
    write_system(directory, "plain")
    values = "".join(f'<InitialValue variable="{k}"><Real value="{v!r}"/></InitialValue>'
                     for k, v in MASS2_START.items())
    path = directory / "alone.xml"
    path.write_text(f'<?xml version="1.0" encoding="utf-8"?>\n<OspSystemStructure xmlns="{OSP_NAMESPACE}" '
                    'version="0.1"><StartTime>0.0</StartTime><EndTime>10.0</EndTime>'
                    '<BaseStepSize>0.001</BaseStepSize><Algorithm>fixedStep</Algorithm>'  # libcosim needs Algorithm
                    '<Simulators><Simulator name="mass2" source="mass2.fmu" '
                    f'stepSize="0.001"><InitialValues>{values}</InitialValues></Simulator></Simulators>'
                    "</OspSystemStructure>\n")
    run = run_osp(path, END_TIME, [("mass2", "x2"), ("mass2", "v2")])
    theirs = {"x2": run[("mass2", "x2")], "v2": run[("mass2", "v2")]}
    table.add("`mass2.fmu` alone", "libcosim", "a one-simulator OSP file", None, None)
    result = simulate_fmu(str(directory / "mass2.fmu"), start_values=dict(MASS2_START), stop_time=END_TIME,
                          output_interval=0.001, output=["x2", "v2"])
    ours = {"x2": np.asarray(result["x2"]), "v2": np.asarray(result["v2"])}
    if len(ours["x2"]) != len(theirs["x2"]):
        table.add("`mass2.fmu` alone", "FMPy simulate_fmu", "output_interval 0.001", None,
                  f"{len(ours['x2'])} samples, libcosim {len(theirs['x2'])}", "libcosim")
        return
    table.add("`mass2.fmu` alone", "FMPy simulate_fmu", "output_interval 0.001", None, difference(ours, theirs),
              "libcosim")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--zenoh", action="store_true", help="also run the peer pair over Zenoh (a few seconds)")
    parser.add_argument("--out", type=Path, help="write the markdown table to this file")
    args = parser.parse_args()
    started = time.perf_counter()
    table = Table()
    reference = analytic_x2()
    with tempfile.TemporaryDirectory(prefix="zencosim-interop-") as tmp:
        root = Path(tmp)
        peer_pair(table, root / "peer", reference, args.zenoh)
        signals_and_ssp(table, root / "signals", reference)
        domains(table, root / "domains", reference)
        examples(table, root / "examples", reference)
        single_fmu(table, root / "single")
    text = table.markdown()
    print(text, end="")
    print(f"({time.perf_counter() - started:.0f} s)", file=sys.stderr)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
