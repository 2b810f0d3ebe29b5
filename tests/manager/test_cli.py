"""The command line as a user runs it."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO
from zencosim.manager.scene.load import bundled_scene_names


def zencosim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, cwd=REPO,
                          timeout=120)


def test_scenes_lists_every_bundled_scene():
    result = zencosim("scenes")
    assert result.returncode == 0
    for name in bundled_scene_names():
        assert name in result.stdout


def test_run_writes_a_summary_with_the_documented_keys(tmp_path):
    out = tmp_path / "s.json"
    result = zencosim("run", "two_mass_damped", "--summary", str(out), "--set", "manager.duration=1.0")
    assert result.returncode == 0, result.stderr
    summary = json.loads(out.read_text())
    for key in ("scene", "bus", "macro_step", "duration", "steps", "effects", "stable", "signals", "energy",
                "residual_energy", "timing", "digest"):
        assert key in summary
    assert summary["steps"] == 1000 and summary["bus"] == "inproc"
    assert set(summary["signals"]) == {"x2", "fc"}
    assert {"nrms", "nrms_monolithic"} <= set(summary["signals"]["x2"])
    assert {"initial", "final", "max_relative_drift"} <= set(summary["energy"])
    assert {"wall_s", "steps_per_s", "step_us_median", "step_us_p99"} <= set(summary["timing"])
    assert len(summary["digest"]) == 64
    assert "NRMS x2 (of its range)" in result.stdout and "NRMS x2 [m]" not in result.stdout  # no unit: normalised


def test_realtime_run_is_paced_to_the_wall_clock(tmp_path, record_property):
    out = tmp_path / "s.json"
    result = zencosim("run", "two_mass_damped", "--realtime", "--quiet", "--summary", str(out),
                      "--set", "manager.duration=0.5")
    assert result.returncode == 0, result.stderr
    timing = json.loads(out.read_text())["timing"]
    for key in ("lateness_us_median", "lateness_us_p99", "lateness_us_max", "missed_deadlines"):
        record_property(key, timing[key])
    # facts that hold on a busy machine (tests/manager/test_pacing.py checks each step; the figures are
    # bench_realtime.py's): every step paced, 500 steps of 1 ms take at least 499 ms
    assert timing["realtime"] and timing["paced_steps"] == 500
    assert timing["wall_s"] >= 0.499
    assert 0 <= timing["lateness_us_median"] <= timing["lateness_us_p99"] <= timing["lateness_us_max"]
    assert 0 <= timing["missed_deadlines"] <= 500


def test_bad_arguments_exit_2():
    assert zencosim("run", "two_mass_damped", "--bus", "carrier-pigeon").returncode == 2
    assert zencosim("run", "two_mass_damped", "--set", "novalue").returncode == 2
    inproc_with_router = zencosim("run", "two_mass_damped", "--connect", "tcp/127.0.0.1:7447")
    assert inproc_with_router.returncode == 2 and "add --bus zenoh" in inproc_with_router.stderr


def test_a_router_that_cannot_listen_says_where_in_one_line():
    result = zencosim("router", "--listen", "tcp/192.0.2.1:7447")  # TEST-NET-1: not an address of this host
    assert result.returncode == 1
    assert "cannot start the router: cannot listen on tcp/192.0.2.1:7447" in result.stderr and "Traceback" not in result.stderr


def test_docker_compose_is_a_run_through_its_router_with_valid_command_lines(tmp_path):
    # no container engine runs here: what is checked is that every service's command parses, names a real
    # scene, that everyone connects to the router service's port over TLS, that the manager waits for exactly
    # the subsystems the other services serve, and that docker/certificates.sh makes every certificate and key
    # a service names, signed by the authority they all name
    import yaml

    from zencosim.cli.main import build_parser
    from zencosim.manager.scene.load import load_scene
    services = yaml.safe_load((REPO / "docker" / "compose.yaml").read_text())["services"]
    args = {name: build_parser().parse_args(service["command"]) for name, service in services.items()}
    assert {a.command for a in args.values()} == {"router", "run", "subsystem"}
    (router,) = [name for name, a in args.items() if a.command == "router"]
    port = args[router].listen[0].rpartition(":")[2]
    (manager,) = [a for a in args.values() if a.command == "run"]
    served = {a.name: a for a in args.values() if a.command == "subsystem"}
    assert set(manager.external) == set(served)
    assert args[router].listen[0].startswith("tls/")
    for name, a in args.items():
        if name != router:
            assert a.connect == [f"tls/{router}:{port}"], name
            scene = load_scene(a.scene, a.overrides)
            assert set(served) <= set(scene.subsystems), name
    # one image, built once: one service builds it, every service runs it by name
    assert len({service["image"] for service in services.values()}) == 1
    assert sum("build" in service for service in services.values()) == 1
    (built,) = [service["build"] for service in services.values() if "build" in service]
    copied = {line.split()[1] for line in (REPO / "docker" / "Dockerfile").read_text().splitlines()
              if line.startswith("COPY ")} | {"pyproject.toml", "setup.py", "README.md", "LICENSE"}
    let_in = {line[1:] for line in (REPO / ".dockerignore").read_text().splitlines() if line.startswith("!")}
    assert built["context"] == ".." and copied - {"./"} <= let_in  # the context holds what the image copies
    assert manager.record and manager.record.startswith("/out/") and "./out:/out" in services["manager"]["volumes"]
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command to make the certificates")
    subprocess.run(["sh", str(REPO / "docker" / "certificates.sh"), str(tmp_path)], check=True, capture_output=True,
                   timeout=120)
    for name, a in args.items():
        assert "./certs:/certs:ro" in services[name]["volumes"], name
        ca, cert, key = (tmp_path / Path(path).relative_to("/certs") for path in (a.tls_ca, a.tls_cert, a.tls_key))
        assert ca.name == "ca.pem" and key.read_text().startswith("-----BEGIN PRIVATE KEY-----"), name
        verified = subprocess.run(["openssl", "verify", "-CAfile", str(ca), str(cert)], capture_output=True, text=True)
        assert verified.returncode == 0, (name, verified.stdout + verified.stderr)


def test_version_names_zencosim_its_protocol_and_what_a_run_depends_on():
    from importlib.metadata import version

    from zencosim.manager.wire.protocol import VERSION
    result = zencosim("--version")
    assert result.returncode == 0
    assert result.stdout.strip().startswith(f"zencosim {version('zencosim')} (wire protocol {VERSION}; "
                                            f"zenoh {version('eclipse-zenoh')}, numpy {version('numpy')}, python ")


def test_version_is_answered_without_importing_the_runtime():
    """As the ``zencosim`` script runs it: the versions from the package metadata, and nothing of zencosim.manager,
    numpy or zenoh imported (the whole runtime once: seconds of CPU for one line)."""
    script = ("import sys\nsys.argv = ['zencosim', '--version']\nfrom zencosim.cli.main import main\nstatus = main()\n"
              "print([m for m in sys.modules\n"
              "       if m.split('.')[0] in ('numpy', 'zenoh') or m.startswith('zencosim.manager')])\n"
              "sys.exit(status)")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert result.returncode == 0, result.stderr
    answer, imported = result.stdout.strip().splitlines()
    assert answer == zencosim("--version").stdout.strip() and answer.startswith("zencosim ")
    assert imported == "[]"


def test_help_shows_examples_for_the_tool_and_each_command():
    assert "examples:" in zencosim("--help").stdout
    for command in ("run", "check", "analyze", "stability", "subsystem", "replay", "inspect", "export"):
        result = zencosim(command, "--help")
        assert result.returncode == 0 and f"zencosim {command}" in result.stdout.split("examples:")[1], command


def test_a_run_whose_reference_energy_is_not_finite_prints_its_summary():
    """v0 = 1e300: the values overflow (exit 3, diverged), the reference's energy too; the summary says so. A
    built-in model refuses such a velocity (its plausibility bounds, docs/scenes.md); a Python model's start
    values are its own."""
    result = zencosim("run", "zencosim/examples/scenes/two_mass_damped_python.toml",
                      "--set", "subsystems.S1.start.v0=1e300", "--set", "outputs.reference=solve_ivp",
                      "--set", "manager.duration=0.01")
    assert result.returncode == 3 and "Traceback" not in result.stderr, result.stderr
    assert "energy final, reference [J]" in result.stdout and "not available (not finite)" in result.stdout


def test_integers_too_large_for_a_float_are_one_line_errors(tmp_path):
    """An integer of 400 digits (no float holds it) and one of 5000 (more than Python reads from text): exit 2,
    naming the file and key, never a traceback."""
    text = (REPO / "scenes" / "two_mass_damped.toml").read_text()
    for digits, message in ((400, "subsystems.S1.bodies.m1.mass: expected a finite number, 1e-9 ≤ mass ≤ 1e9 [kg], "
                                  "got an integer of 400 digits"),
                            (5000, "scene: an integer of more than 4300 digits")):
        scene = tmp_path / f"big{digits}.toml"
        scene.write_text(text.replace("mass = 1.0, x0 = 0.0", f"mass = {'9' * digits}, x0 = 0.0", 1))
        result = zencosim("check", str(scene))
        assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
        assert f"{scene}: {message}" in result.stderr, result.stderr


@pytest.mark.parametrize("kind", ["device", "pipe", "pipe.xml", "folder"])
def test_a_scene_that_is_no_regular_file_is_one_line_and_exit_2(tmp_path, kind):
    """``zencosim check /dev/zero`` (or a named pipe, as a TOML scene or an OSP file) read forever once."""
    import contextlib
    import io
    import os

    from zencosim.cli.main import main
    if kind == "device":
        path = Path("/dev/zero")
        if not path.exists():
            pytest.skip("no /dev/zero here")
    elif kind == "folder":
        path = tmp_path
    else:
        path = tmp_path / ("scene.toml" if kind == "pipe" else "OspSystemStructure.xml")
        os.mkfifo(path)
    key = "file" if path.suffix == ".xml" else "scene"
    for command in (["check", str(path)], ["run", str(path), "--quiet"]):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as errors:
            assert main(command) == 2, errors.getvalue()
        assert f"{path}: {key}: not a regular file; expected a TOML scene" in " ".join(errors.getvalue().split())
