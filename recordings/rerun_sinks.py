"""Where a Rerun view goes: a file, a viewer spawned here, a viewer or server elsewhere, or the web viewer.

``spawn``: a native viewer started here (the ``rerun`` that rerun-sdk installs beside this Python, else
the one on PATH), on ``SPAWN_PORT`` — or the viewer already listening there. A viewer needs a display:
without one, or without the executable, or when the viewer does not start listening, the error says
so (``ViewerError``, exit status 2) instead of streaming into nothing. ``connect=ADDR``: a viewer or
``rerun --serve-grpc`` at ``ADDR`` (``HOST:PORT`` or a ``rerun+http://…/proxy`` URL). ``serve``: a
gRPC server in this process and the web viewer on ``WEB_PORT``; it lasts as long as the process.
"""
from __future__ import annotations

import os
import shutil
import socket
import sys
import time
from pathlib import Path

import rerun as rr

from zencosim.recordings import RecordingError

SPAWN_PORT = 9876  # Rerun's own default: a viewer already open there is reused
WEB_PORT = 9090
LISTEN_TIMEOUT_S = 2.0  # after spawning, the viewer must accept connections within this time


class ViewerError(RecordingError):
    """No viewer to show a run in; the message says why and what to do instead."""


def viewer_url(address: str) -> str:
    """The gRPC URL of ``HOST:PORT``, ``PORT`` or a ``rerun+http(s)://…/proxy`` URL."""
    if "://" in address:
        return address
    host, _, port = address.rpartition(":")
    return f"rerun+http://{host or '127.0.0.1'}:{port}/proxy"


def _listening(port: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return True
        except OSError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)


def spawn_viewer(stream: rr.RecordingStream, port: int = SPAWN_PORT) -> rr.GrpcSink:
    """A native viewer for ``stream`` (see the module text); ViewerError when there can be none."""
    if _listening(port, 0.0):
        return rr.GrpcSink(viewer_url(str(port)))
    beside = Path(sys.executable).with_name("rerun")
    executable = str(beside) if beside.exists() else shutil.which("rerun")
    if executable is None:
        raise ViewerError("no Rerun viewer: the 'rerun' executable is neither beside this Python nor on PATH "
                          "(pip install 'zencosim[rerun]'); write a file with --rrd FILE instead")
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ViewerError("no display for a Rerun viewer (DISPLAY and WAYLAND_DISPLAY are unset): write a file "
                          "with --rrd FILE and open it where there is one (rerun FILE), or serve the web viewer")
    rr.spawn(port=port, connect=False, executable_path=executable, recording=stream)
    if not _listening(port, LISTEN_TIMEOUT_S):
        raise ViewerError(f"the Rerun viewer ({executable}) did not start listening on port {port}: write a file "
                          "with --rrd FILE instead")
    return rr.GrpcSink(viewer_url(str(port)))


def serve_web(stream: rr.RecordingStream) -> str:
    """A gRPC server for ``stream`` in this process and the web viewer connected to it; its address."""
    uri = rr.serve_grpc(recording=stream)
    rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=uri)
    return f"http://127.0.0.1:{WEB_PORT}"
