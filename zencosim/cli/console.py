"""What every command shares: the consoles, the scene arguments, and messages that name what they concern."""
from __future__ import annotations

import argparse
import os

from rich.console import Console
from rich.markup import escape

from zencosim.manager.wire.text import printable


class UsageError(ValueError):
    """Arguments that do not fit together (exit status 2)."""


PIPED_WIDTH = 200  # columns of output that is not a terminal (a pipe, a log file): rich would cut tables at 80


def _console(stderr: bool = False) -> Console:
    """A console as wide as its terminal; output that is not a terminal gets ``PIPED_WIDTH`` columns (unless
    ``COLUMNS`` says otherwise), so that a table written to a file or a pipe is not cut or wrapped at 80."""
    console = Console(stderr=stderr)
    if console.is_terminal or "COLUMNS" in os.environ:
        return console
    return Console(stderr=stderr, width=PIPED_WIDTH)


out = _console()
err = _console(stderr=True)


def say(text: str) -> None:
    """Print plain text (no markup, no highlighting, control characters escaped) on standard output."""
    out.print(escape(printable(text)), highlight=False, soft_wrap=True)


def warn(text: str) -> None:
    """Print plain text on standard error (as :func:`say`: errors and log tails hold text from the network)."""
    err.print(escape(printable(text)), highlight=False, soft_wrap=True)


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="a bundled scene name (see 'zencosim scenes') or a path to a TOML scene")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scalar of the scene, e.g. --set manager.macro_step=0.004 (repeatable)")


def share(text: str) -> float:
    """An argument that is a share in [0, 1] (of steps, of deadlines)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a share in [0, 1]")
    return value


def examples(*lines: str) -> dict:
    """``add_parser`` options that show ``lines`` as examples at the end of the command's help."""
    return {"epilog": "examples:\n" + "\n".join(f"  {line}" for line in lines),
            "formatter_class": argparse.RawDescriptionHelpFormatter}
