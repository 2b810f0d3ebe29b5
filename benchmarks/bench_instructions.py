"""Instructions per in-process macro-step of two_mass_damped and of its plain-Python floor, counted by valgrind.

    python benchmarks/bench_instructions.py [--tree DIR] [--recording] [--fmu] [--replicas] [--chains 3,33]

``zencosim.run`` counts a run as a user makes it (``zencosim.run(zencosim.load_scene("two_mass_damped", …))``):
the stepping loop, the references and the summary, which must grow with the samples, not cost a second run.
Wall time on a shared machine swings with what else runs; the number of instructions a step executes
does not. Each figure is the difference of two runs under ``valgrind --tool=cachegrind`` (``STEPS``
macro-steps apart) divided by the difference in steps, so start-up and imports cancel. numpy's BLAS
runs on one thread (``OPENBLAS_NUM_THREADS=1``): its idle worker threads spin for a while after each
call, and their instructions made two counts of the same run differ by a third. String hashes are fixed
(``PYTHONHASHSEED=0``): with random ones, dict probes differ from run to run (two counts of the same step
were 80 instructions apart, with the seed fixed 1). ``--tree DIR``
(repeatable) counts the in-process step of another source tree too (see bench_runtime.py).
``--recording`` counts what recording adds to the stepping loop: the loop alone, with the manager's
status, and with the status and the recorder's tap (its frames dropped: no recorder process). ``--fmu`` counts
the same system with both subsystems as the example C FMUs (``zencosim examples``: two_mass_damped_fmu.toml, and
the FMI 3.0 ones of two_mass_damped_fmu3.toml) and,
where libcosimpy is installed, libcosim stepping the same two FMUs from an OSP file of that scene (issue 26's
reference: 9,382 instructions per step). ``--replicas`` counts what the two subsystem processes of a Zenoh run
compute per step besides Zenoh (``replicas.py``: their replicas in one thread, each reply handed to the other);
``--chains 3,33`` the same for chains of masses (``zencosim.scenes.topologies``), per process (the mean over its
processes): what a process computes per step should not grow with n. Needs valgrind.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

STEPS = (500, 2500)
# the floor's runs lie further apart: its 2,000-step difference is 7.6 M instructions, where the noise of a run's
# start (a few million instructions) moved its per-step count between 3,755 and 4,869; 40,000 steps dilute it
FLOOR_STEPS = (500, 40_500)
# the FMU pairs' too: a run also compiles the one-call step at its start (``fmi_steps``: a compiler as a child
# process), and two counts of the same 2,000-step difference came out 2,641 and 13,735 instructions per step
FMU_STEPS = (500, 10_500)
# a run as a user makes it: both runs longer than the spike detector's 2 s window, so that the difference counts
# its steady work per point; at (500, 2,500) the shorter run judged no point, and the difference held one-time
# costs (stop 36's detector: 3,200 instructions per step counted from 500 to 2,500 steps, 2,373 from 10,000 to 30,000)
USER_STEPS = (3000, 13_000)
ONE_RUN = """
import sys
sys.path.insert(0, {benchmarks!r})
from floor import floor_x2, parameters
if sys.argv[3] == "flat":  # a tree from before the package: manager is a top-level package
    from manager.run import execute
    from manager.scene import load_scene
else:
    from zencosim.manager.run import execute
    from zencosim.manager.scene.load import load_scene
scene = load_scene("two_mass_damped", [f"manager.duration={{int(sys.argv[2]) / 1000}}"])
if sys.argv[1].startswith("fmu"):  # the example FMUs' scene (fmu3: the FMI 3.0 ones), in the directory argv[4]
    execute(load_scene(sys.argv[4] + f"/two_mass_damped_{{sys.argv[1]}}.toml",
                       [f"manager.duration={{int(sys.argv[2]) / 1000}}"]), "inproc")
elif sys.argv[1] == "libcosim":  # the same FMUs stepped by libcosim from the OSP file in argv[4]
    from libcosimpy.CosimExecution import CosimExecution
    execution = CosimExecution.from_osp_config_file(sys.argv[4])
    execution.simulate_until(int(sys.argv[2]) * 1_000_000)
elif sys.argv[1] == "floor":
    floor_x2(parameters(scene), int(sys.argv[2]))
elif sys.argv[1] == "run":
    execute(scene, "inproc")
elif sys.argv[1] == "user":  # a run as a user makes it: references and summary included
    import zencosim
    zencosim.run(zencosim.load_scene("two_mass_damped", {{"manager.duration": int(sys.argv[2]) / 1000}}))
elif sys.argv[1] == "replicas":  # the subsystem processes' replicas, their replies handed across in this thread
    from replicas import replicas_in_lock_step
    replicas_in_lock_step(scene)
elif sys.argv[1].startswith("chain"):  # the same for a chain of argv[1][5:] masses (zencosim.scenes.topologies)
    import tempfile
    from replicas import replicas_in_lock_step
    from zencosim.scenes.topologies import mass_chain
    with tempfile.NamedTemporaryFile("w", suffix=".toml") as written:
        written.write(mass_chain(int(sys.argv[1][5:]), int(sys.argv[2]) / 1000))
        written.flush()
        replicas_in_lock_step(load_scene(written.name))
else:  # the stepping loop: "plain", with the "status", with the status and the "tap"
    from bench_recording import stepping_loop
    from zencosim.manager.assembly import plan_scene
    stepping_loop(scene, sys.argv[1], *plan_scene(scene))
"""


def counted(program: str, arguments: list[str], pythonpath: str, label: str) -> int:
    """The instructions valgrind counts in ``python -c program *arguments`` (PYTHONPATH ``pythonpath``); ``label``
    names the run where it fails. bench_ffi.py counts with it too."""
    env = {**os.environ, "PYTHONPATH": pythonpath, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PYTHONHASHSEED": "0"}
    # `python -c` imports from its working directory first (from the repository's root: this tree's zencosim,
    # whatever PYTHONPATH says), so it runs in the temporary directory; and once without valgrind first: a module
    # changed since its last import is compiled to bytecode then, not in the first of the two counted runs (which
    # made the floor's count 1,400 instructions per step too low)
    subprocess.run([sys.executable, "-c", program, *arguments], env=env, capture_output=True,
                   cwd=tempfile.gettempdir(), check=False)
    result = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
                             sys.executable, "-c", program, *arguments],
                            env=env, capture_output=True, text=True, cwd=tempfile.gettempdir())
    if result.returncode != 0:  # name the run and show why, instead of a bare CalledProcessError
        raise SystemExit(f"{label} failed under valgrind with status {result.returncode}:\n{result.stderr[-2000:]}")
    return int(re.search(r"I\s+refs:\s+([\d,]+)", result.stderr).group(1).replace(",", ""))


def instructions(what: str, steps: int, pythonpath: str, layout: str, where: str = "") -> int:
    return counted(ONE_RUN.format(benchmarks=str(Path(__file__).resolve().parent)), [what, str(steps), layout, where],
                   pythonpath, f"bench_instructions: {what} of {steps} steps ({pythonpath or 'this tree'})")


def per_step(what: str, pythonpath: str = "", layout: str = "package", where: str = "") -> float:
    steps = (FLOOR_STEPS if what == "floor" else FMU_STEPS if what.startswith(("fmu", "libcosim"))
             else USER_STEPS if what == "user" else STEPS)
    low, high = (instructions(what, n, pythonpath, layout, where) for n in steps)
    return (high - low) / (steps[1] - steps[0])


def fmu_pair(show) -> None:
    """The in-process step with both subsystems as the example C FMUs, and libcosim's step of the same FMUs."""
    from zencosim.examples.write import write_examples
    with tempfile.TemporaryDirectory() as directory:
        write_examples(Path(directory))
        zencosim_count = per_step("fmu", where=directory)
        show("in-process step, two C FMUs", zencosim_count)
        show("in-process step, two C FMUs, FMI 3.0", per_step("fmu3", where=directory))
        try:
            import libcosimpy  # noqa: F401
            sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
            from tests.interop.scene_osp import write_osp
        except ImportError as error:
            print(f"libcosim not counted: {error}", flush=True)
            return
        osp = write_osp(Path(directory) / "two_mass_damped_fmu.toml", Path(directory) / "OspSystemStructure.xml")
        libcosim_count = per_step("libcosim", where=str(osp))
        show(f"libcosim's step, the same FMUs (zencosim: {zencosim_count / libcosim_count:.1f}x)", libcosim_count)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="also count the step of this source tree (before/after; repeatable)")
    parser.add_argument("--recording", action="store_true", help="also count the step with the status and the tap")
    parser.add_argument("--fmu", action="store_true", help="also count the step with two C FMUs, and libcosim's")
    parser.add_argument("--replicas", action="store_true",
                        help="also count the two subsystem processes' own work per step, without Zenoh")
    parser.add_argument("--chains", default="",
                        help="sizes of chains (e.g. 3,33) whose processes' work per step and process to count")
    args = parser.parse_args()
    if shutil.which("valgrind") is None:
        print("bench_instructions needs valgrind (apt-get install valgrind)", file=sys.stderr)
        return 2
    floor = per_step("floor")

    def show(label: str, count: float) -> None:  # as soon as it is counted: a later failure keeps it
        print(f"{label:60} {count:10.0f} instructions per macro-step  ({count / floor:.1f}x the floor)", flush=True)

    show("floor: the same arithmetic as one Python loop", floor)
    run = per_step("run")
    show("in-process step, this tree", run)
    show("zencosim.run, references and summary included", per_step("user"))
    if args.recording:
        plain = per_step("plain")
        show("stepping loop alone", plain)
        for what, label in (("status", "stepping loop with the status"), ("tap", "stepping loop with status and tap")):
            count = per_step(what)
            show(f"{label} (+{100 * (count / plain - 1):.1f} %)", count)
    if args.fmu:
        fmu_pair(show)
    if args.replicas:
        show("subsystem processes' replicas, both, without Zenoh", per_step("replicas"))
    for n in filter(None, args.chains.split(",")):  # issue 26: a chain's process costs the same at every n
        show(f"chain of {n}: one process's replica, mean, without Zenoh", per_step(f"chain{n}") / int(n))
    for tree in args.tree:
        from bench_runtime import package_farm
        farm = package_farm(tree)
        flat = farm == tree.resolve()
        try:
            layout = "flat" if flat else "package"
            show(f"in-process step, tree {tree}", per_step("run", str(farm), layout))
            if not flat:
                show(f"zencosim.run, tree {tree}", per_step("user", str(farm), layout))
        finally:
            if not flat:
                shutil.rmtree(farm)
    return 0


if __name__ == "__main__":
    sys.exit(main())
