"""Files a run or a command writes, checked before the work starts: a missing directory or an unknown
suffix is an error that names the file, not a traceback after the run."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence


class OutputFileError(ValueError):
    """An output file that cannot be written; the message names the file and what it is for."""


def check_output_file(path: str | Path, what: str, suffixes: Sequence[str] = ()) -> Path:
    """``path`` as a :class:`Path` once it can be written: its directory exists and is writable, it is not a
    directory itself, and (when ``suffixes`` are given) it ends in one of them."""
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise OutputFileError(f"{what} {path}: unknown file type {path.suffix or '(no suffix)'!r}; "
                              f"expected one of {', '.join(suffixes)}")
    if path.is_dir():
        raise OutputFileError(f"{what} {path}: is a directory; expected a file name")
    directory = path.parent
    if not directory.is_dir():
        raise OutputFileError(f"{what} {path}: the directory {directory} does not exist")
    if not os.access(directory, os.W_OK):
        raise OutputFileError(f"{what} {path}: the directory {directory} is not writable")
    return path
