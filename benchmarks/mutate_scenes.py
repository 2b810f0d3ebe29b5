"""How zencosim takes N mutated scene files (issue 14): clean errors, tracebacks, accepted-but-broken.

Every mutant (``tests/manager/scene_mutations.py``: keys deleted, types swapped, extreme and non-finite numbers,
unicode and unsafe names, deep nesting) goes through ``zencosim check`` (its ``main``, in this process, so that an
exception that escapes it is the traceback a user would see). An accepted scene is broken when:

* it has no macro-step (``duration < macro_step``);
* its arrays cannot fit: ``n_ticks * 8 B * (outputs per tick + 2 per bond + 1)`` exceeds the available memory;
* a subsystem's name is not one plain Zenoh key segment (``zenoh.KeyExpr``: invalid, a wildcard, ``/`` or a
  leading ``@``);
* ``zencosim run`` of its first macro-step period (``--set manager.duration=<one period>``, in process)
  raises, exits 1 or 2, writes a summary that is not strict JSON, or exits 0 although a value is not finite.

A run that reports its divergence (exit status 3) is not broken. Usage::

    python benchmarks/mutate_scenes.py -n 2400 --seed 14

Measured (issue 14, seed 14): before the checks of issue 14, 2,400 mutants gave 1,825 clean errors, 186 tracebacks
(14 distinct) and 411 accepted of which 39 broken (20 summaries not strict JSON, 7 runs failing, 4 without a
macro-step, 4 beyond the memory, 4 hanging in the solve_ivp reference); after them, 2,046 clean errors, 2 tracebacks
(an overflow in the solve_ivp reference, since caught) and 354 accepted of which 9 broken (8 runs that fail cleanly
with exit status 1 — a model's maths module overflows, or a micro-step too fine for the timeout — and 1 run whose
first period took over 120 s on a machine loaded 25-fold).
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import io
import json
import math
import random
import signal
import sys
import tempfile
import traceback
from pathlib import Path

import zenoh

from zencosim.cli.main import main
from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the mutator lives with the tests
from tests.manager.scene_mutations import mutated_scene  # noqa: E402

TIME_LIMIT_S = 120  # a mutant's check and short run together; longer counts as broken ("hangs")


class Hung(Exception):
    pass


def _alarm(signum, frame):
    raise Hung


def available_bytes() -> int:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no MemAvailable in /proc/meminfo")


def quiet_main(argv: list[str]) -> int:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


def plain_key_segment(name: str) -> bool:
    """True when ``name`` is one Zenoh key chunk that is neither a wildcard nor a hidden (``@``) chunk."""
    try:
        key = str(zenoh.KeyExpr(f"zencosim/run/{name}/y"))
    except Exception:
        return False
    return key.split("/")[2] == name and key.count("/") == 3 and "*" not in name and not name.startswith("@")


def _strict(text: str):
    def refuse(constant):
        raise ValueError(f"non-standard JSON constant {constant}")
    return json.loads(text, parse_constant=refuse)


def _finite(value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_finite(v) for v in value)
    return True


def why_broken(path: Path, folder: Path) -> str | None:
    """Why a scene that ``check`` accepted cannot run, or None."""
    scene = load_scene(str(path))
    plan, _ = plan_scene(scene)
    if plan.n_ticks < 1:
        return "no macro-step"
    width = sum(len(s.outputs) / s.ratio for s in plan.subsystems) + 2 * len(plan.bonds) + 1
    if plan.n_ticks * 8 * width > available_bytes():
        return "arrays larger than the available memory"
    unsafe = [name for name in scene.subsystems if not plain_key_segment(name)]
    if unsafe:
        return f"subsystem name not a plain Zenoh key segment: {unsafe[0]!r}"
    period_ns = plan.base_step_ns * math.lcm(*(s.ratio for s in plan.subsystems))
    summary = folder / "summary.json"
    summary.unlink(missing_ok=True)
    status = quiet_main(["run", str(path), "--quiet", "--summary", str(summary),
                         "--set", f"manager.duration={period_ns * 1e-9!r}"])
    if status in (1, 2):
        return f"one-period run exits {status}"
    if status not in (0, 3):
        return f"one-period run exits {status}"
    try:
        document = _strict(summary.read_text())
    except ValueError as error:
        return f"summary is not strict JSON: {error}"
    if status == 0 and not _finite(document):
        return "exit 0 with a value that is not finite"
    return None


def main_script() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-n", type=int, default=2400, help="mutants (default 2400)")
    parser.add_argument("--seed", type=int, default=14)
    parser.add_argument("--show", type=int, default=3, help="examples shown per kind of outcome")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    counts = collections.Counter()
    tracebacks: dict[str, list[str]] = collections.defaultdict(list)
    broken: dict[str, list[str]] = collections.defaultdict(list)
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "scene.toml"
        for i in range(args.n):
            text, what = mutated_scene(rng)
            path.write_text(text)
            signal.alarm(TIME_LIMIT_S)
            try:
                status = quiet_main(["check", str(path)])
                if status == 2:
                    counts["clean error"] += 1
                    continue
                counts["accepted"] += 1
                reason = why_broken(path, folder)
                if reason is not None:
                    counts["accepted but broken"] += 1
                    broken[reason.split(":")[0]].append(f"{what} -> {reason}")
            except Hung:
                counts["accepted but broken"] += 1
                broken["hangs"].append(what)
            except BaseException as error:  # noqa: BLE001 — a traceback is what is counted
                if isinstance(error, KeyboardInterrupt):
                    raise
                counts["traceback"] += 1
                frame = traceback.extract_tb(error.__traceback__)[-1]
                where = f"{type(error).__name__} at {Path(frame.filename).name}:{frame.lineno}"
                tracebacks[where].append(f"{what} -> {str(error)[:100]!r}")
            finally:
                signal.alarm(0)
            if (i + 1) % 200 == 0:
                print(f"{i + 1}: {dict(counts)}", file=sys.stderr, flush=True)
    print(f"{args.n} mutated scenes (seed {args.seed}): {counts['clean error']} clean errors, "
          f"{counts['traceback']} tracebacks ({len(tracebacks)} distinct), {counts['accepted']} accepted of which "
          f"{counts['accepted but broken']} broken")
    for title, groups in (("tracebacks", tracebacks), ("accepted but broken", broken)):
        for where, examples in sorted(groups.items(), key=lambda item: -len(item[1])):
            print(f"  {title}: {len(examples)} x {where}")
            for example in examples[:args.show]:
                print(f"      {example!r}")


if __name__ == "__main__":
    main_script()
