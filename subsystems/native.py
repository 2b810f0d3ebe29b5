"""C files shipped in the package, compiled with the system's C compiler when first needed, and kept.

Two hot loops leave Python this way: an FMU's communication step as one foreign call
(``subsystems/models/external/fmi_steps.c``) and a generated macro-step loop run as a register program
(``manager/scheme/register_loop.c``). A file is compiled with ``$CC`` (else ``cc`` or ``gcc``) into a temporary
directory (50–100 ms), loaded, and a copy kept in the cache (``$ZENCOSIM_CACHE_DIR``, else
``~/.cache/zencosim``: ``native/<file>-<key>.so``), from which the next process loads it without compiling; the key
is the SHA-256 of the source, the compiler's path, its flags and the machine, so a changed file or another compiler
compiles anew. A copy goes into the cache whole (written beside it, then renamed) or not at all; a cache that cannot
be written or read is passed by. It needs no Python headers and changes nothing at install. ``-ffp-contract=off``: no
multiply-add is fused, so that every floating-point operation rounds as Python's does. Where no compiler is found,
it fails, or the temporary directory cannot be written or is mounted ``noexec``, :func:`library` is None and the
callers keep their Python paths.
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from importlib import resources
from pathlib import Path

COMPILE_TIMEOUT_S = 120  # a compiler still running after this long is given up on: the Python path runs
FLAGS = ("-O2", "-ffp-contract=off", "-shared", "-fPIC")
CACHE_DIR = "ZENCOSIM_CACHE_DIR"  # the environment variable that moves the cache (default ~/.cache/zencosim)


@functools.cache
def library(package: str, file_name: str) -> ctypes.CDLL | None:
    """``file_name`` of ``package`` compiled and loaded, once per process (from the cache where it is there); None
    where no C compiler is found or it fails."""
    compiler = c_compiler()
    if compiler is None:
        return None
    source = resources.files(package).joinpath(file_name).read_bytes()
    key = hashlib.sha256(b"\0".join([source, os.path.realpath(compiler).encode(), *(f.encode() for f in FLAGS),
                                     platform.machine().encode()])).hexdigest()[:16]
    cached = cache_dir() / "native" / f"{Path(file_name).stem}-{key}.so"
    try:
        return ctypes.CDLL(str(cached))
    except OSError:  # not there yet (or not loadable): compile it
        pass
    try:  # a temporary directory that cannot be written, or whose files cannot be mapped (noexec): none
        with tempfile.TemporaryDirectory(prefix="zencosim-native-") as directory:
            c_file, shared = Path(directory) / file_name, Path(directory) / cached.name
            c_file.write_bytes(source)
            built = subprocess.run([compiler, *FLAGS, str(c_file), "-o", str(shared)], capture_output=True,
                                   timeout=COMPILE_TIMEOUT_S, check=False)
            if built.returncode != 0:
                return None
            compiled = ctypes.CDLL(str(shared))  # loaded: the file can go
            _keep(shared, cached)
            return compiled
    except (OSError, subprocess.TimeoutExpired):
        return None


def c_compiler() -> str | None:
    """The C compiler's path: ``$CC``, else ``cc`` or ``gcc``; None where none is found."""
    return shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")


def cache_dir() -> Path:
    """Where zencosim keeps what it made once to use again: ``$ZENCOSIM_CACHE_DIR``, else ``~/.cache/zencosim``."""
    return Path(os.environ.get(CACHE_DIR) or Path.home() / ".cache" / "zencosim")


def _keep(shared: Path, cached: Path) -> None:
    """A copy of ``shared`` at ``cached``, whole or not at all (written beside it, then renamed); nothing where the
    cache cannot be written."""
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        descriptor, partial = tempfile.mkstemp(dir=cached.parent, prefix=f".{cached.name}-")
    except OSError:
        return
    try:
        with os.fdopen(descriptor, "wb") as copy:
            copy.write(shared.read_bytes())
        os.replace(partial, cached)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(partial)
