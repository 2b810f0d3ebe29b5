"""The child processes of a run (subsystem processes, the recorder): started from the installed zencosim,
ending with their parent.

A child runs ``python -P -m <module>`` with the parent's interpreter: ``-P`` keeps the working directory
(and the script's directory) off the import path, so a ``manager.py`` or a ``recordings/`` folder
where the user works cannot shadow zencosim's modules, while ``PYTHONPATH`` and the environment's
site-packages still apply. On Linux a child gets SIGTERM when its parent dies, even by SIGKILL, so
that none is orphaned: the child asks for it itself (``end_with_parent``, as its ``main`` starts), so
that the parent starts it without a ``preexec_fn`` — with one, subprocess forks instead of vforking, the
parent's memory turns copy-on-write, and every page the parent writes afterwards faults once (about
7 400 faults, 1.5 µs each on this host, in the first steps of a recorded in-process run).
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

PARENT_PID = "ZENCOSIM_PARENT_PID"  # set by start_child for the child's end_with_parent


def start_child(module: str, arguments: list[str], **popen_options) -> subprocess.Popen:
    """Start ``python -P -m module arguments…`` as a child that ends with this process (its ``main`` calls
    ``end_with_parent``)."""
    env = {**(popen_options.pop("env", None) or os.environ), PARENT_PID: str(os.getpid())}
    return subprocess.Popen([sys.executable, "-P", "-m", module, *arguments], env=env, **popen_options)


def end_with_parent() -> None:
    """In a child started by ``start_child`` (Linux): get SIGTERM when the parent dies, even by SIGKILL
    (``PR_SET_PDEATHSIG``); a parent that died while this process started sends it at once. Elsewhere, and in
    a process nobody started that way, nothing."""
    parent = os.environ.pop(PARENT_PID, None)
    if parent is None or not sys.platform.startswith("linux"):
        return
    PR_SET_PDEATHSIG = 1
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != int(parent):  # reparented: the parent was gone before the request
        os.kill(os.getpid(), signal.SIGTERM)


# the state letter of /proc/PID/stat (proc(5)) as a reason a process does not answer
_STATES = {"T": "is frozen (process stopped, state T: SIGSTOP or a debugger)",
           "t": "is frozen (process stopped by a tracer, state t)",
           "D": "is stuck in the kernel (state D, uninterruptible wait)",
           "Z": "has exited (state Z)"}


def stat_fields(pid: int) -> list[str]:
    """The fields of ``/proc/PID/stat`` after the process's name (proc(5): the state first, then its parent, …);
    empty where they cannot be read (not Linux, or the process is gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return []


def process_state(pid: int) -> str | None:
    """Linux: why process ``pid`` does not answer, from its state in ``/proc/PID/stat`` ("is frozen (process
    stopped, …)", "has exited", …); None when it runs or sleeps normally, or the state cannot be read."""
    fields = stat_fields(pid)
    return _STATES.get(fields[0]) if fields else None


def working(pid: int) -> bool:
    """Linux: whether process ``pid`` is running, waiting only for a CPU (state R) or for its disk (state D): slowed
    by a busy machine, not waiting for something that may never come."""
    fields = stat_fields(pid)
    return bool(fields) and fields[0] in ("R", "D")


def cpu_time_s(pid: int, fields: list[str] | None = None) -> float:
    """The CPU time [s] process ``pid`` has used so far (user and system, ``/proc/PID/stat``, or its ``fields``
    already read; 0 where they cannot be read)."""
    fields = stat_fields(pid) if fields is None else fields
    try:
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (IndexError, ValueError):
        return 0.0


def wait_while_working(pid: int, stall_s: float, look_s: float = 0.1) -> bool:
    """Linux: wait for process ``pid``, not necessarily a child, to exit, for as long as it makes progress (uses CPU,
    or waits only for a CPU or its disk); True once it has exited, False once it made none for ``stall_s``."""
    still_from, cpu = time.monotonic(), cpu_time_s(pid)
    while (fields := stat_fields(pid)) and fields[0] not in ("Z", "X"):
        time.sleep(look_s)
        now, used = time.monotonic(), cpu_time_s(pid)
        if used > cpu or working(pid):
            still_from, cpu = now, used
        elif now - still_from >= stall_s:
            return False
    return True


def exit_reason(returncode: int) -> str:
    """``"killed by SIGKILL"`` or ``"exited with code 3"`` for a ``Popen.returncode``."""
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exited with code {returncode}"
