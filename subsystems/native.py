"""C files shipped in the package, compiled with the system's C compiler when first needed.

Two hot loops leave Python this way: an FMU's communication step as one foreign call
(``subsystems/models/external/fmi_steps.c``) and a generated macro-step loop run as a register program
(``manager/scheme/register_loop.c``). A file is compiled with ``$CC`` (else ``cc`` or ``gcc``) into a temporary
directory once per process (about 40 ms), loaded, and the file removed. It needs no Python headers and changes nothing
at install. ``-ffp-contract=off``: no multiply-add is fused, so that every floating-point operation rounds as Python's
does. Where no compiler is found, it fails, or the temporary directory cannot be written or is mounted ``noexec``,
:func:`library` is None and the callers keep their Python paths.
"""
from __future__ import annotations

import ctypes
import functools
import os
import shutil
import subprocess
import tempfile
from importlib import resources
from pathlib import Path

COMPILE_TIMEOUT_S = 120  # a compiler still running after this long is given up on: the Python path runs


@functools.cache
def library(package: str, file_name: str) -> ctypes.CDLL | None:
    """``file_name`` of ``package`` compiled and loaded, once per process; None where no C compiler is found or it
    fails."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if compiler is None:
        return None
    source = resources.files(package).joinpath(file_name).read_bytes()
    try:  # a temporary directory that cannot be written, or whose files cannot be mapped (noexec): none
        with tempfile.TemporaryDirectory(prefix="zencosim-native-") as directory:
            c_file, shared = Path(directory) / file_name, Path(directory) / f"{Path(file_name).stem}.so"
            c_file.write_bytes(source)
            built = subprocess.run([compiler, "-O2", "-ffp-contract=off", "-shared", "-fPIC", str(c_file),
                                    "-o", str(shared)], capture_output=True, timeout=COMPILE_TIMEOUT_S, check=False)
            return ctypes.CDLL(str(shared)) if built.returncode == 0 else None  # loaded: the file can go
    except (OSError, subprocess.TimeoutExpired):
        return None
