"""Pictures of the Rerun replay for the docs: two_mass_damped and the hydraulic crane, in the web viewer.

    python docs/screenshots.py [--out docs/images]

Records each scene in process, replays the recording into a Rerun file (``zencosim replay --rrd``),
serves the file with the web viewer (``rerun --serve-web``) and photographs it with headless Chromium
(Debian's ``chromium``: ``apt-get install chromium``; not needed by the tests). Chromium runs without a
GPU, sandbox or network (WebGL through its software renderer) in a new, empty profile, and is driven
over the DevTools protocol on a pipe (``--remote-debugging-pipe``: JSON messages ended by a NUL byte),
so no websocket library is needed. The viewer loads the recording and draws it in software, which
takes minutes on a busy machine: the page is photographed every ``POLL_S`` and the picture kept once
two in a row are the same (the view has settled), after at most ``LOAD_TIMEOUT_S``. The viewer without the
recording is photographed first: a picture of the run that equals that welcome page fails, naming the file (a
viewer that did not load the recording once reported success with the welcome page).

The Rerun server and Chromium each start a process group of their own (``rerun`` from rerun-sdk is a
Python launcher that starts the viewer's binary; Chromium starts its helpers), and the whole group is
ended, also when a picture fails.
"""
from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENES = {  # picture → scene and overrides
    "two_mass_damped": ("two_mass_damped", []),
    "hydraulic_crane": ("hydraulic_crane", []),
}
WINDOW = (1600, 1000)  # [px]
POLL_S = 15.0  # [s] between two pictures of the page
LOAD_TIMEOUT_S = 900.0  # [s] the viewer has settled within this time (software rendering on a busy machine)
STOP_TIMEOUT_S = 10.0  # [s] a process group ended with SIGTERM is killed after this
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--enable-unsafe-swiftshader", "--hide-scrollbars")  # WebGL in software: the viewer needs it


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _zencosim(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "zencosim", *args], check=True)


def _wait_listening(port: int, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.1)
    raise RuntimeError(f"nothing listens on port {port} after {timeout_s} s")


def _stop(process: subprocess.Popen) -> None:
    """End ``process`` and every process of its group (it leads one: ``start_new_session``)."""
    try:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    except ProcessLookupError:
        process.wait()
    try:  # what the leader left behind
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def _pipes_at_3_and_4(commands: int, results: int) -> None:
    """In the child: the DevTools pipe's ends where Chromium expects them (it reads 3, writes 4)."""
    commands, results = os.dup(commands), os.dup(results)  # above 4, so that the first dup2 cannot close the other
    os.dup2(commands, 3)
    os.dup2(results, 4)


class DevTools:
    """Chromium driven over ``--remote-debugging-pipe``: ``call`` sends a command and returns its result."""

    def __init__(self, chromium: str, profile: str) -> None:
        commands_read, self._commands = os.pipe()
        self._results, results_write = os.pipe()
        self.process = subprocess.Popen(
            [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
             "--remote-debugging-pipe", "about:blank"],
            pass_fds=(3, 4), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
            preexec_fn=lambda: _pipes_at_3_and_4(commands_read, results_write))
        os.close(commands_read)
        os.close(results_write)
        self._next = 0
        self._buffer = b""

    def call(self, method: str, session: str | None = None, **params) -> dict:
        self._next += 1
        message = {"id": self._next, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self._commands, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._buffer:
                chunk = os.read(self._results, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"chromium closed the pipe during {method}")
                self._buffer += chunk
            text, self._buffer = self._buffer.split(b"\0", 1)
            answer = json.loads(text)
            if answer.get("id") == self._next:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer["result"]

    def close(self) -> None:
        _stop(self.process)
        os.close(self._commands)
        os.close(self._results)


def photograph(rrd: Path, png: Path, chromium: str) -> None:
    """Serve ``rrd`` with the web viewer and save Chromium's picture of it as ``png``."""
    rerun = Path(sys.executable).with_name("rerun")
    web, grpc = _free_port(), _free_port()
    server = subprocess.Popen([str(rerun), "--serve-web", "--web-viewer-port", str(web), "--port", str(grpc), str(rrd)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_listening(web)
        _wait_listening(grpc)
        # as rerun prints it: "localhost" in both, which its gRPC server allows as an origin (CORS)
        url = f"http://localhost:{web}?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A{grpc}%2Fproxy"
        with tempfile.TemporaryDirectory(prefix="zencosim-chromium-") as profile:
            browser = DevTools(chromium, profile)
            try:
                target = browser.call("Target.createTarget", url="about:blank")["targetId"]
                session = browser.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
                browser.call("Emulation.setDeviceMetricsOverride", session, width=WINDOW[0], height=WINDOW[1],
                             deviceScaleFactor=1, mobile=False)
                # the viewer without a recording first: its welcome page, which a picture of the run must not be
                browser.call("Page.navigate", session, url=f"http://localhost:{web}")
                welcome = _settled(browser, session)
                browser.call("Page.navigate", session, url=url)
                picture = _settled(browser, session)
                if picture == welcome:
                    raise RuntimeError(f"the viewer shows its welcome page, not {rrd.name}: nothing to photograph")
                png.write_bytes(picture)
            finally:
                browser.close()
    finally:
        _stop(server)


def _settled(browser: DevTools, session: str) -> bytes:
    """The page's picture once two taken ``POLL_S`` apart are the same."""
    deadline = time.monotonic() + LOAD_TIMEOUT_S
    previous = None
    while time.monotonic() < deadline:
        time.sleep(POLL_S)
        shot = base64.b64decode(browser.call("Page.captureScreenshot", session, format="png")["data"])
        if shot == previous:
            return shot
        previous = shot
    raise RuntimeError(f"the viewer was still changing after {LOAD_TIMEOUT_S:g} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).parent / "images"), help="folder of the pictures")
    args = parser.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        sys.exit("no chromium on PATH: apt-get install chromium")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="zencosim-screenshots-") as tmp:
        for picture, (scene, overrides) in SCENES.items():
            mcap, rrd = Path(tmp) / f"{picture}.mcap", Path(tmp) / f"{picture}.rrd"
            _zencosim("run", scene, *(a for o in overrides for a in ("--set", o)), "--quiet", "--record", str(mcap))
            _zencosim("replay", str(mcap), "--rrd", str(rrd))
            photograph(rrd, out / f"replay_{picture}.png", chromium)
            print(f"wrote {out / f'replay_{picture}.png'}")


if __name__ == "__main__":
    main()
