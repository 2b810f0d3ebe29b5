"""Damaged recordings through ``zencosim inspect`` and ``zencosim replay --verify``: tracebacks, clean errors, passes.

Records two_mass_damped for 3 s (3000 macro-steps, 15 004 messages), makes ``--copies`` damaged copies
of the file (seeded: the same copies every time; an equal share of each kind of
``tests/recordings/corruption.py``: one bit flipped, several bits flipped, cut off, two chunks swapped,
a byte range zeroed, a bit flipped in a record outside the chunks), and runs both commands on each,
in process, through the command line's ``main`` (so an exit status is what a user sees). A *false
pass* is exit status 0 on a copy whose bytes differ from the intact file. Then a crafted recording
(a 10-step run whose embedded scene, digest updated, claims ``manager.duration = 1e7`` s) goes through
``replay --verify`` in a subprocess limited to 2 GiB of address space.

    python benchmarks/corrupt_recordings.py [--copies 330] [--seed 14] [--jobs 2]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import multiprocessing
import random
import resource
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import zencosim  # noqa: E402
from tests.recordings.corruption import KINDS, claiming_duration, corrupt  # noqa: E402
from zencosim.cli.main import build_parser, main  # noqa: E402
from zencosim.recordings.reader import read_recording  # noqa: E402

build_parser()  # imports every command's module now


def outcome(argv: list[str]) -> str:
    """'exit N', or 'traceback <exception type>'."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            return f"exit {main(argv)}"
        except SystemExit as stop:
            return f"exit {stop.code}"
        except Exception as error:  # noqa: BLE001 - what escapes is the finding (Ctrl-C and SIGTERM still stop this)
            frame = traceback.extract_tb(error.__traceback__)[-1]
            return f"traceback {type(error).__name__} ({Path(frame.filename).name}:{frame.lineno})"


_intact = b""
_directory = Path()


def _given(intact: bytes, directory: Path) -> None:
    global _intact, _directory
    _intact, _directory = intact, directory


def _check(copy: tuple[int, str, int, int]) -> tuple[bool, dict[str, str]]:
    """Whether damaged copy ``n`` is byte-identical to the intact file, and each command's outcome on it."""
    n, kind, a, b = copy
    data = corrupt(_intact, kind, a, b)
    path = _directory / f"damaged{n}.mcap"
    path.write_bytes(data)
    outcomes = {command: outcome(argv) for command, argv in (("inspect", ["inspect", str(path)]),
                                                             ("verify", ["replay", str(path), "--verify"]))}
    path.unlink()
    return data == _intact, outcomes


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=330)
    parser.add_argument("--seed", type=int, default=14)
    parser.add_argument("--jobs", type=int, default=2, help="processes checking copies in parallel")
    args = parser.parse_args()
    directory = Path(tempfile.mkdtemp(prefix="corrupt_recordings_"))
    intact_path = directory / "run.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=3.0"]), record=intact_path)
    intact = intact_path.read_bytes()
    print(f"recording: {intact_path}, {len(intact)} bytes, "
          f"{sum(len(c.messages) for c in read_recording(intact_path).channels.values())} messages")
    rng = random.Random(args.seed)
    copies = [(n, KINDS[n % len(KINDS)], rng.randrange(1 << 40), rng.randrange(1 << 40)) for n in range(args.copies)]
    started = time.perf_counter()
    counts = {command: Counter() for command in ("inspect", "verify")}
    tracebacks = {command: Counter() for command in ("inspect", "verify")}
    unchanged = 0
    with multiprocessing.get_context("fork").Pool(args.jobs, initializer=_given, initargs=(intact, directory)) as pool:
        for done, (same, outcomes) in enumerate(pool.imap(_check, copies), 1):
            unchanged += same
            for command, result in outcomes.items():
                if result.startswith("traceback"):
                    counts[command]["traceback"] += 1
                    tracebacks[command][result.removeprefix("traceback ")] += 1
                elif result == "exit 0":
                    counts[command]["exit 0, intact copy" if same else "exit 0, damaged copy (false pass)"] += 1
                else:
                    counts[command][result] += 1
            if done % 30 == 0 and done < len(copies):
                print(f"  after {done} copies: " + "; ".join(
                    f"{command} " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())) for command, c in counts.items()),
                    flush=True)
    print(f"{args.copies} damaged copies (seed {args.seed}; {unchanged} of them byte-identical to the intact file), "
          f"{time.perf_counter() - started:.0f} s")
    for command in counts:
        print(f"  {command}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts[command].items())))
        for what, v in tracebacks[command].most_common():
            print(f"      {v} x {what}")

    small = directory / "small.mcap"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=0.01"]), record=small)
    bomb = claiming_duration(small, directory / "crafted.mcap", 1e7)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    started = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "zencosim", "replay", str(bomb), "--verify"], capture_output=True,
                         text=True, preexec_fn=limit, timeout=600)
    last = (run.stderr.strip() or run.stdout.strip()).splitlines()[-1:] or [""]
    print(f"crafted {bomb.stat().st_size}-byte recording claiming 1e7 s, replay --verify under 2 GiB: exit "
          f"{run.returncode} after {time.perf_counter() - started:.1f} s: {last[0][:300]}")


if __name__ == "__main__":
    main_()
