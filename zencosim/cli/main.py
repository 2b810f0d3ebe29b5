"""The ``zencosim`` command line (also ``python -m zencosim``).

Exit status: 0 success, 1 a run failed (a subsystem died, stopped answering or reported an error) or
a recording did not verify, 2 bad input (scene, overrides, arguments, recording file, output path,
a missing optional dependency), 130 interrupted (SIGINT or SIGTERM).
"""
from __future__ import annotations

import argparse
import platform
import signal
import sys
from importlib.metadata import version

from zencosim.cli import analysis, models, recordings, run, scenes, study, subsystem
from zencosim.cli.console import UsageError, err, examples, warn
from zencosim.extras import MissingExtra
from zencosim.manager.results.output_files import OutputFileError
from zencosim.manager.scene.load import SceneError
from zencosim.manager.scheme.base import SubsystemFailure
from zencosim.manager.wire.protocol import VERSION, ProtocolError
from zencosim.recordings import RecordingError
from zencosim.subsystems.process.host import HostError

COMMANDS = (scenes, run, analysis, study, recordings, subsystem, models)  # each adds its parsers
BAD_INPUT = (SceneError, RecordingError, OutputFileError, MissingExtra, UsageError)  # exit status 2
RUN_FAILED = (SubsystemFailure, ProtocolError, HostError)  # exit status 1


def versions() -> str:
    """zencosim's version and those a run depends on (two hosts of a run should show the same)."""
    return (f"zencosim {version('zencosim')} (wire protocol {VERSION}; zenoh {version('eclipse-zenoh')}, "
            f"numpy {version('numpy')}, python {platform.python_version()})")


def build_parser() -> argparse.ArgumentParser:
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
    for command in COMMANDS:
        command.add_parsers(commands)
    return parser


def _interrupt(signum: int, _frame) -> None:
    """SIGTERM ends a run like Ctrl-C: subsystems are stopped and the recording is finished."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return args.handler(args)
    except BAD_INPUT as error:
        err.print("[bold red]error:[/]", highlight=False, end=" ")
        warn(str(error))
        return 2
    except RUN_FAILED as error:
        err.print("[bold red]run failed:[/]", highlight=False, end=" ")
        warn(str(error))
        return 1
    except KeyboardInterrupt:
        err.print("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(main())
