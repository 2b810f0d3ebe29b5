"""The ``zencosim`` command line (also ``python -m zencosim``).

Exit status: 0 success, 1 a run failed (a subsystem died, stopped answering or reported an error; the
recorder was lost under --record-lost stop) or a recording did not verify (damaged, cut off or different;
``inspect``: damaged or cut off), 2 bad input (scene, overrides, arguments, recording file, output path, a missing
optional dependency, a Zenoh session that cannot open: an endpoint to listen on that is taken, a
certificate file missing), 3 a run completed but diverged (a value not finite, or an implicit run's joint
opened; its summary and tables are still written) or, with ``run --strict``, its verdict is unstable or a
real-time run missed more than ``--max-missed`` of its deadlines (reported, exit 0, without it), 130
interrupted (SIGINT or SIGTERM).
"""
from __future__ import annotations

import argparse
import importlib
import signal
import sys

from zencosim.versions import versions

# the modules of zencosim.cli, each adds its parsers
COMMANDS = ("scenes", "run", "realtime", "analysis", "study", "recordings", "subsystem", "router", "models")
# a run starts one `zencosim subsystem` process per subsystem: it imports its own command only (about 0.5 s of CPU
# instead of 0.85 s each, which 33 processes starting on 2 cores feel)
SUBSYSTEM_ONLY = "subsystem"
# `zencosim --version` is answered from the package metadata before anything of the runtime is imported (many
# times the CPU of the answer); every other command imports what it runs when it runs
VERSION_ONLY = ["--version"]


def outcomes() -> tuple[tuple[type[Exception], ...], tuple[type[Exception], ...]]:
    """The exceptions of bad input (exit status 2) and of a run that failed (exit status 1)."""
    from zencosim.cli.console import UsageError
    from zencosim.extras import MissingExtra
    from zencosim.manager.bus.router import RouterError
    from zencosim.manager.bus.security import SecurityError
    from zencosim.manager.bus.zenoh_session import SessionError
    from zencosim.manager.results.output_files import OutputFileError
    from zencosim.manager.scene.load import SceneError
    from zencosim.manager.scheme.base import SubsystemFailure
    from zencosim.manager.wire.protocol import ProtocolError
    from zencosim.recordings import RecorderLost, RecordingError
    from zencosim.subsystems.process.host import HostError
    return ((SceneError, RecordingError, OutputFileError, MissingExtra, UsageError, SecurityError, SessionError),
            (SubsystemFailure, ProtocolError, HostError, RouterError, RecorderLost))


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or of ``subsystem`` only when that is the ``command``."""
    from zencosim.cli.console import examples
    parser = argparse.ArgumentParser(
        prog="zencosim", description="Distributed, real-time co-simulation over Eclipse Zenoh",
        **examples("zencosim scenes                                   # the bundled benchmarks of the papers",
                   "zencosim check four_mass                          # validate a scene, show ports and effects",
                   "zencosim run two_mass_damped --bus zenoh          # one process per subsystem",
                   "zencosim run two_mass_damped --out results.csv    # every signal with its time",
                   "zencosim run two_mass_damped --record run.mcap && zencosim replay run.mcap --verify",
                   "zencosim COMMAND --help                           # the options and examples of a command"))
    parser.add_argument("--version", action="version", version=versions(),
                        help="print the versions of zencosim, its wire protocol, zenoh, numpy and python")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in (SUBSYSTEM_ONLY,) if command == SUBSYSTEM_ONLY else COMMANDS:
        importlib.import_module(f"zencosim.cli.{module}").add_parsers(commands)
    return parser


def _interrupt(signum: int, _frame) -> None:
    """SIGTERM ends a run like Ctrl-C: subsystems are stopped and the recording is finished."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """The command line's exit status for ``argv`` (default: the process's arguments). Run from the command line
    (``argv`` None), ``run --bus inproc`` and ``replay --verify`` (whose re-run is in process) run in a child process
    that this one watches (``manager.bus.watchdog``): a model that ends or hangs the process is named."""
    command_line = argv is None
    argv = sys.argv[1:] if command_line else argv
    if argv == VERSION_ONLY:
        print(versions())
        return 0
    args = build_parser(argv[0] if argv else None).parse_args(argv)
    from zencosim.manager.bus.watchdog import WATCHABLE, watched
    if command_line and args.command == "run" and args.bus == "inproc" and WATCHABLE:
        return watched(lambda: _handle(args), _failed)
    if command_line and args.command == "replay" and args.verify and WATCHABLE:  # its re-run is an in-process run
        return watched(lambda: _handle(args), _rerun_failed)
    return _handle(args)


def _failed(reason: str, what: str = "run failed:") -> None:
    from zencosim.cli.console import err, warn
    err.print(f"[bold red]{what}[/]", highlight=False, end=" ")
    warn(reason)


def _rerun_failed(reason: str) -> None:
    _failed(reason, "the re-run failed:")


def _handle(args: argparse.Namespace) -> int:
    """Run the command ``args`` names; its exit status (see the module text)."""
    from zencosim.cli.console import err, warn
    from zencosim.manager.bus.children import end_with_parent
    bad_input, run_failed = outcomes()
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        end_with_parent()  # a subsystem process: SIGTERM (an interrupt, as above) when its manager dies
        return args.handler(args)
    except bad_input as error:
        err.print("[bold red]error:[/]", highlight=False, end=" ")
        warn(str(error))
        return 2
    except run_failed as error:
        _failed(str(error))
        return 1
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
