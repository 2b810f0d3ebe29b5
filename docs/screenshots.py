"""Pictures of the Rerun replay for the docs: two_mass_damped and the hydraulic crane, in the web viewer.

    python docs/screenshots.py [--out docs/images]

Records each scene in process, replays the recording into a Rerun file (``zencosim replay --rrd``),
serves the file with the web viewer (``rerun --serve-web``) and photographs it with headless Chromium
(Debian's ``chromium``: ``apt-get install chromium``; not needed by the tests). Chromium runs without a
GPU, sandbox or network (WebGL through its software renderer) in a new, empty profile.
"""
from __future__ import annotations

import argparse
import shutil
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
LOAD_BUDGET_MS = 40_000  # virtual time Chromium gives the viewer to load the recording before the picture
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--enable-unsafe-swiftshader", "--hide-scrollbars")


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


def photograph(rrd: Path, png: Path, chromium: str) -> None:
    """Serve ``rrd`` with the web viewer and save Chromium's picture of it as ``png``."""
    rerun = Path(sys.executable).with_name("rerun")
    web, grpc = _free_port(), _free_port()
    server = subprocess.Popen([str(rerun), "--serve-web", "--web-viewer-port", str(web), "--port", str(grpc), str(rrd)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_listening(web)
        _wait_listening(grpc)
        url = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
        with tempfile.TemporaryDirectory(prefix="zencosim-chromium-") as profile:
            subprocess.run([chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                            f"--window-size={WINDOW[0]},{WINDOW[1]}", f"--virtual-time-budget={LOAD_BUDGET_MS}",
                            f"--screenshot={png.resolve()}", url], check=True, timeout=300,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    finally:
        server.terminate()
        server.wait()


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
