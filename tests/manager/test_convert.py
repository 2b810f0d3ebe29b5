"""``zencosim convert`` writes only a scene that ``zencosim check`` accepts (issue 25, item 2).

It used to write, for an OSP system whose EndTime is 1e7 s, a scene that ``check`` then refused (the run's arrays
need terabytes). The scene is now checked before it is written, as ``check`` checks it (loaded, then planned):
one that would not load is not written (a file of that name stays as it was), the problems are reported as
``check`` reports the system description's, exit status 2 (docs/system-imports.md).
"""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.manager.test_cli import zencosim
from tests.manager.test_system_imports import OSP_MODEL_DESCRIPTION, osp_system, write_fmu
from zencosim.manager.assembly import plan_scene
from zencosim.manager.scene.load import load_scene


@pytest.fixture(scope="module")
def oscillator_fmu(tmp_path_factory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("building the example FMU needs gcc")
    from zencosim.examples.fmus.build import build_fmu
    return build_fmu(tmp_path_factory.mktemp("fmu") / "oscillator.fmu", 2, ("cs",))


def _system(directory: Path, fmu: Path | None, end: str) -> Path:
    directory.mkdir()
    if fmu is None:
        write_fmu(directory / "oscillator.fmu")  # its modelDescription.xml only: no binary
        (directory / "oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)
    else:
        shutil.copy(fmu, directory / "oscillator.fmu")
        (directory / "zencosim oscillator_OspModelDescription.xml").write_text(OSP_MODEL_DESCRIPTION)  # its modelName
    path = directory / "OspSystemStructure.xml"
    path.write_text(osp_system(end=f"<EndTime>{end}</EndTime>"))
    return path


def test_a_scene_check_would_refuse_is_not_written_and_the_reason_is_one_line_each(oscillator_fmu, tmp_path):
    system = _system(tmp_path / "system", oscillator_fmu, "1e7")
    target = tmp_path / "scene.toml"
    target.write_text("# a scene of the user's, kept\n")
    result = zencosim("convert", str(system), "--to", str(target))
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    lines = " ".join(result.stderr.split())
    assert f"{system}: manager.duration: 1e+07 s in macro-steps of 0.001 s is 10,000,000,000 macro-steps" in lines
    assert (f"{system}: --to: {target} not written: the scene converted from this file would not load (zencosim "
            f"check {system} shows the same); --duration SECONDS sets manager.duration") in lines
    assert target.read_text() == "# a scene of the user's, kept\n"
    check = zencosim("check", str(system))  # the same problem, as check states it
    assert check.returncode == 2 and f"{system}: manager.duration: 1e+07 s" in " ".join(check.stderr.split())


def test_with_a_duration_that_fits_it_writes_a_scene_that_check_accepts(oscillator_fmu, tmp_path):
    system = _system(tmp_path / "system", oscillator_fmu, "1e7")
    target = tmp_path / "out" / "scene.toml"
    target.parent.mkdir()
    result = zencosim("convert", str(system), "--to", str(target), "--duration", "10")
    assert result.returncode == 0, result.stderr
    scene = load_scene(str(target))
    plan, _ = plan_scene(scene)  # what check does
    assert scene.manager.duration == 10.0 and plan.n_ticks == 10_000
    assert scene.subsystems["S1"].spec.start["v0"] == 100.0
    assert zencosim("check", str(target)).returncode == 0


def test_an_fmu_without_a_binary_for_this_platform_is_not_written(tmp_path):
    """check refuses it (the FMU could not run here); convert says so instead of writing it."""
    system = _system(tmp_path / "system", None, "10.0")
    target = tmp_path / "scene.toml"
    result = zencosim("convert", str(system), "--to", str(target))
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    lines = " ".join(result.stderr.split())
    assert f"{system}: subsystems.S1.fmu: FMU " in lines and "has no binary for this platform" in lines
    assert f"{system}: --to: {target} not written" in lines and "--duration" not in lines
    assert not target.exists()
