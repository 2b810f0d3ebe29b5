"""The child processes of a run (subsystem processes, the recorder): started from the installed zencosim,
ending with their parent.

A child runs ``python -P -m <module>`` with the parent's interpreter: ``-P`` keeps the working directory
(and the script's directory) off the import path, so a ``manager.py`` or a ``recordings/`` folder
where the user works cannot shadow zencosim's modules, while ``PYTHONPATH`` and the environment's
site-packages still apply. On Linux a child gets SIGTERM when its parent dies, even by SIGKILL, so
that none is orphaned.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
from pathlib import Path


def die_with_parent() -> None:
    """Linux: the calling process gets SIGTERM when its parent dies (``PR_SET_PDEATHSIG``)."""
    PR_SET_PDEATHSIG = 1
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def start_child(module: str, arguments: list[str], **popen_options) -> subprocess.Popen:
    """Start ``python -P -m module arguments…`` as a child that ends with this process."""
    return subprocess.Popen([sys.executable, "-P", "-m", module, *arguments],
                            preexec_fn=die_with_parent if sys.platform.startswith("linux") else None, **popen_options)


# the state letter of /proc/PID/stat (proc(5)) as a reason a process does not answer
_STATES = {"T": "is frozen (process stopped, state T: SIGSTOP or a debugger)",
           "t": "is frozen (process stopped by a tracer, state t)",
           "D": "is stuck in the kernel (state D, uninterruptible wait)",
           "Z": "has exited (state Z)"}


def _stat_fields(pid: int) -> list[str]:
    """The fields of ``/proc/PID/stat`` after the process's name (proc(5): the state first, then its parent, …);
    empty where they cannot be read (not Linux, or the process is gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return []


def process_state(pid: int) -> str | None:
    """Linux: why process ``pid`` does not answer, from its state in ``/proc/PID/stat`` ("is frozen (process
    stopped, …)", "has exited", …); None when it runs or sleeps normally, or the state cannot be read."""
    fields = _stat_fields(pid)
    return _STATES.get(fields[0]) if fields else None


def cpu_time_s(pid: int) -> float:
    """The CPU time [s] process ``pid`` has used so far (user and system, ``/proc/PID/stat``; 0 where it cannot
    be read)."""
    fields = _stat_fields(pid)
    try:
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (IndexError, ValueError):
        return 0.0


def exit_reason(returncode: int) -> str:
    """``"killed by SIGKILL"`` or ``"exited with code 3"`` for a ``Popen.returncode``."""
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exited with code {returncode}"
