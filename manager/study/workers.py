"""The study's workers: processes that measure points in process, one point at a time each.

A worker is ``python -m zencosim.manager.study.workers``: it reads one task per line on its standard input
(JSON: ``key``, ``scene``, ``overrides``, ``repeats``, ``signals_file``) and writes one line per task on its
standard output (``key`` and ``measured``, or ``key`` and ``error``); it ends at the end of its input. Plain processes
rather than a ``multiprocessing`` pool: nothing of the caller's main module is imported again, and the
study ends its workers by their process ids whatever happens.
"""
from __future__ import annotations

import json
import selectors
import signal
import subprocess
import sys
import traceback
from typing import Callable, Iterator


def measure_tasks(tasks: list[dict], workers: int) -> Iterator[tuple[str, dict]]:
    """``(key, measured)`` of every task, in the order they finish, measured by ``workers`` processes; a task
    that fails raises ``RuntimeError`` naming its point."""
    pending = list(reversed(tasks))
    processes: list[subprocess.Popen] = []  # filled one by one: an interrupt while they start ends those started
    selector = selectors.DefaultSelector()
    try:
        for _ in range(min(workers, len(tasks))):
            processes.append(subprocess.Popen([sys.executable, "-m", "zencosim.manager.study.workers"],
                                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1))
        for process in processes:
            _give(process, pending)
            selector.register(process.stdout, selectors.EVENT_READ, process)
        busy = len(processes)
        while busy:
            for ready, _ in selector.select():
                process = ready.data
                line = process.stdout.readline()
                if not line:
                    raise RuntimeError(f"a study worker (pid {process.pid}) ended with status {process.wait()} "
                                       "before it finished its point")
                answer = json.loads(line)
                if "error" in answer:
                    raise RuntimeError(f"point {answer['key']}: {answer['error']}")
                yield answer["key"], answer["measured"]
                if not _give(process, pending):
                    selector.unregister(process.stdout)
                    busy -= 1
    finally:
        selector.close()
        for process in processes:
            if process.poll() is None:
                process.kill()
            process.wait()
            process.stdout.close()
            if process.stdin and not process.stdin.closed:
                try:
                    process.stdin.close()
                except BrokenPipeError:
                    pass


def _give(process: subprocess.Popen, pending: list[dict]) -> bool:
    """Send ``process`` the next task, or close its input (it then ends); True when it got a task."""
    if pending:
        process.stdin.write(json.dumps(pending.pop()) + "\n")
        process.stdin.flush()
        return True
    process.stdin.close()
    return False


def serve(measure: Callable[[str, tuple[str, ...], int, str | None], dict]) -> None:
    """A worker's loop (module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the study ends its workers itself
    for line in sys.stdin:
        task = json.loads(line)
        try:
            answer = {"key": task["key"], "measured": measure(task["scene"], tuple(task["overrides"]), task["repeats"],
                                                           task.get("signals_file"))}
        except Exception:
            answer = {"key": task["key"], "error": traceback.format_exc(limit=4)}
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    from zencosim.manager.study.measure import measure_point
    serve(measure_point)
