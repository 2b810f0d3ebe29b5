"""Instructions per macro-step of the manager's replica over Zenoh, without Zenoh, counted by valgrind.

    python benchmarks/bench_manager_replica.py [--scenes two_mass_damped,star17,star33]

Over Zenoh the manager follows the run with a replica of the scheme that computes every command and takes every
reply from the network, screening each (``manager.scheme.replica``). Here the replies of a run are made first, by
the subsystem processes' replicas in one thread (``replicas.py``), and written to a file; then a fresh
process feeds them to the manager's replica under ``valgrind --tool=cachegrind``, for runs ``STEPS`` apart, and
the difference over the steps is the count (start-up and imports cancel; as bench_instructions.py: one BLAS
thread, fixed string hashes). Two ways, side by side: ``batches``, as the manager follows a run (``follower``: it
may take whole steps at once, ``manager.scheme.followed_blocks``; each subsystem's replies in batches of
``LOG_REPLIES``, as its process sends them, ``subsystems.process.host``), and ``one by one`` (the replica that takes
reply after reply, as before the blocks). ``starN`` is the star of N masses of ``zencosim.scenes.topologies``: its hub's
fan-in, and the manager's, is N − 1. Needs valgrind.
"""
from __future__ import annotations

import argparse
import os
import pickle
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from replicas import replicas_in_lock_step

from zencosim.manager.scene.load import load_scene

STEPS = (500, 2500)

FEED = """
import pickle, sys
from zencosim.manager.assembly import make_scheme, plan_scene
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.replica import Replica
reference, overrides, replies = pickle.load(open(sys.argv[1], "rb"))
plan, _ = plan_scene(load_scene(reference, overrides))
batches = sys.argv[2] == "batches"
manager = Replica(make_scheme(load_scene(reference, overrides), plan, follower=batches),
                  [s.name for s in plan.subsystems], on_drop=lambda name, reason: None)
manager.start()
if batches:
    from zencosim.subsystems.process.host import LOG_REPLIES
    pending = {s.name: [] for s in plan.subsystems}
    for name, reply in replies:
        pending[name].append(reply)
        if len(pending[name]) == LOG_REPLIES:
            manager.deliver_batches([(name, pending[name])])
            pending[name] = []
    for name, rest in pending.items():
        manager.deliver_batches([(name, rest)])
else:
    for name, reply in replies:
        manager.deliver(name, reply)
assert manager.finished
"""


def scene_of(name: str, steps: int, folder: Path) -> tuple[str, list[str]]:
    """The scene (a bundled name or a written star) and its overrides for a run of ``steps`` 1 ms steps."""
    from zencosim.scenes.topologies import mass_star
    if name.startswith("star"):
        path = folder / f"{name}_{steps}.toml"
        path.write_text(mass_star(int(name[4:]), steps * 1e-3))
        return str(path), []
    return name, [f"manager.duration={steps / 1000!r}"]


def instructions(script: Path, replies: Path, way: str) -> int:
    env = {**os.environ, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1"}
    result = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
                             sys.executable, str(script), str(replies), way], capture_output=True, text=True, env=env,
                            check=True)
    return int(re.search(r"I\s+refs:\s+([\d,]+)", result.stderr).group(1).replace(",", ""))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default="two_mass_damped,star17,star33")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="zencosim-manager-") as temporary:
        folder = Path(temporary)
        script = folder / "feed.py"
        script.write_text(FEED)
        print(f"{'scene':20s} {'one by one':>12s} {'batches':>12s}   instructions per macro-step of the manager's "
              "replica", flush=True)
        for name in args.scenes.split(","):
            paths = []
            for steps in STEPS:
                reference, overrides = scene_of(name, steps, folder)
                paths.append(folder / f"{name}_{steps}.pkl")
                replies = replicas_in_lock_step(load_scene(reference, overrides))
                paths[-1].write_bytes(pickle.dumps((reference, overrides, replies)))
            per_step = {}
            for way in ("one-by-one", "batches"):
                counts = [instructions(script, path, way) for path in paths]
                per_step[way] = (counts[1] - counts[0]) / (STEPS[1] - STEPS[0])
            print(f"{name:20s} {per_step['one-by-one']:12,.0f} {per_step['batches']:12,.0f}", flush=True)

if __name__ == "__main__":
    main()
