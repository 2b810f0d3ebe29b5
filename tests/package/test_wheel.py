"""The wheel users install: one import package, every sub-package, and runs that the working directory
cannot break.

The wheel is built from the repository's files (tracked and new, not ignored) and installed with the
core dependencies only into a fresh virtual environment; the run starts from a working directory that
holds a ``manager.py``, a ``subsystems/`` and a ``recordings/`` folder (the generic names the package
once installed) and a ``zencosim.py`` (which ``python -m`` would import but for ``-P``), all failing
when imported.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import zencosim
from tests.conftest import REPO
from tests.package.conftest import layer_folders

SHADOW = 'raise SystemExit("the working directory\'s {name} was imported instead of zencosim\'s")\n'


def _source_files() -> list[str]:
    listed = subprocess.run(["git", "-C", str(REPO), "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
                            capture_output=True, check=True).stdout.decode().split("\0")
    return [name for name in listed if name and (REPO / name).is_file()]


def _run(command: list[str], cwd: Path, timeout_s: float) -> subprocess.CompletedProcess:
    """Run ``command`` in a process group of its own, killed whole when it ends or times out."""
    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        stdout, stderr = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        stdout, stderr = process.communicate()
        raise AssertionError(f"{' '.join(command)} did not finish within {timeout_s:g} s:\n{stdout}\n{stderr}")
    finally:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return subprocess.CompletedProcess(command, process.returncode, stdout, stderr)


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel, venv) with the wheel of this source tree installed, core dependencies only."""
    base = tmp_path_factory.mktemp("wheel")
    source = base / "source"
    for name in _source_files():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, source / name)
    built = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(base / "dist"), str(source)],
                 base, 600)
    assert built.returncode == 0, built.stderr
    (wheel,) = (base / "dist").glob("zencosim-*.whl")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    install = _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)], base, 900)
    assert install.returncode == 0, install.stderr
    return wheel, venv


@pytest.mark.slow
def test_the_wheel_holds_one_top_level_package_with_every_module_of_the_layer_folders(installed):
    wheel, _ = installed
    names = zipfile.ZipFile(wheel).namelist()
    assert {name.split("/")[0] for name in names if ".dist-info/" not in name} == {"zencosim"}
    expected = set()
    for name in _source_files():
        top = name.split("/")[0]
        if name.endswith(".py") and top == "zencosim":
            expected.add(name)
        elif top in layer_folders() and (name.endswith(".py") or (top == "scenes" and name.endswith(".toml"))):
            expected.add(f"zencosim/{name}")
    assert expected - set(names) == set(), "modules of the source tree missing from the wheel"


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(900)
def test_the_installed_wheel_runs_over_zenoh_from_a_working_directory_that_shadows_its_modules(installed, tmp_path):
    _, venv = installed
    work = tmp_path / "work"
    for folder in ("subsystems", "recordings"):
        (work / folder).mkdir(parents=True)
        (work / folder / "__init__.py").write_text(SHADOW.format(name=f"{folder}/"))
    for module in ("manager.py", "zencosim.py"):
        (work / module).write_text(SHADOW.format(name=module))
    zencosim_cli = str(venv / "bin" / "zencosim")

    result = _run([zencosim_cli, "run", "two_mass_damped", "--bus", "zenoh", "--quiet", "--summary", "summary.json",
                   "--record", "recordings/new.mcap"], work, 300)
    assert result.returncode == 0, result.stderr
    expected = zencosim.run(zencosim.load_scene("two_mass_damped")).digest
    assert json.loads((work / "summary.json").read_text())["digest"] == expected

    verified = _run([zencosim_cli, "replay", "recordings/new.mcap", "--verify"], work, 300)
    assert verified.returncode == 0 and "verify passed" in verified.stdout, verified.stderr

    # the distribution installs one import name (read from its RECORD)
    listed = _run([str(venv / "bin" / "python"), "-P", "-c", "import importlib.metadata as m, json; "
                   "print(json.dumps([str(f) for f in m.files('zencosim')]))"], work, 60)
    files = json.loads(listed.stdout)
    tops = {f.split("/")[0] for f in files if not f.startswith("..") and ".dist-info/" not in f}
    assert tops == {"zencosim"}

    version = _run([str(venv / "bin" / "python"), "-P", "-m", "zencosim", "--version"], work, 60)
    assert version.returncode == 0 and version.stdout.startswith(f"zencosim {zencosim.__version__} (wire protocol")


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(300)
@pytest.mark.parametrize("arguments,extra", [
    (["replay", "{recording}", "--rrd", "view.rrd"], "rerun"),
    (["run", "two_mass_damped", "--set", "manager.duration=0.1", "--out", "results.parquet"], "parquet"),
    (["stability", "--method", "projection", "--decomposition", "force-force", "--k", "0", "--out", "map.png"], "plots"),
    (["analyze", "two_mass_undamped", "--plot", "poles.png"], "plots"),
])
def test_a_command_that_needs_a_missing_extra_exits_2_with_the_pip_command(installed, tmp_path, arguments, extra):
    _, venv = installed
    recording = tmp_path / "run.mcap"
    if "{recording}" in arguments:
        made = _run([str(venv / "bin" / "zencosim"), "run", "two_mass_damped", "--set", "manager.duration=0.1",
                     "--quiet", "--record", str(recording)], tmp_path, 120)
        assert made.returncode == 0, made.stderr
    result = _run([str(venv / "bin" / "zencosim"), *(a.format(recording=recording) for a in arguments)], tmp_path, 120)
    assert result.returncode == 2, result.stderr
    assert f"pip install 'zencosim[{extra}]'" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / arguments[-1]).exists()
