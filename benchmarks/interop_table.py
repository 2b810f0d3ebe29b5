"""zencosim against libcosim (and FMPy) on the same artifacts: a markdown table of what each tool ran and
the largest difference between their trajectories.

    python benchmarks/interop_table.py                      # the table on stdout
    python benchmarks/interop_table.py --zenoh --out table.md

Needs gcc, fmpy and libcosimpy (``pip install -e '.[test]'``). The artifacts are built in a temporary
folder: the peer pair of tests/interop (paper 000's two_mass_damped as two FMUs written for the tests) in
five OSP system structures, and the FMU scenes of ``zencosim examples`` written as OSP files. "largest
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


def zencosim_run(path: Path, bus: str = "inproc"):
    scene = zencosim.load_scene(path)
    (coupling,) = scene.couplings
    result = zencosim.run(scene, bus)
    return result, {"x2": result.signal(f"{coupling}.x").values, "v2": result.signal(f"{coupling}.v").values,
                    "fc": result.signal(f"{coupling}.f").values}


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
