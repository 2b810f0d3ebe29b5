"""A run protected by mutual TLS, across two "hosts", with an intruder on a third (docs/security.md).

Three network namespaces' worth of hosts: this one (the manager, which spawns S1), host B (S2, started
by hand) and the intruder's, each joined to this one by a veth pair on a /30 of the test's own. The
manager listens on every interface, as the README's cross-host example does, so the intruder reaches
its port. Certificates come from a certificate authority the test makes with the ``openssl`` command.
Before S2 joins, while the manager waits for it, the intruder tries plain TCP, TLS without a client
certificate and TLS with a certificate of another authority: it must get no session, no run, no
queryable, no liveliness token and no sample, and its STOP and garbage on the run's keys (the run id
taken from S1's command line: the worst case) must change nothing. The same intruder code with host
B's credentials finds the run, which shows that the code would have found it. Then S2 joins and the
run completes with the in-process digest. Needs root, ``ip`` and ``openssl``; skipped otherwise.

The same on loopback with user/password authentication: a process with no password, a wrong one or
another user's gets nothing of the run and cannot stop it.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.certificates import certificate, certificate_authority
from tests.conftest import children_of, cmdline, read_until, summary_of, wait_for
from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.bus.zenoh_session import free_tcp_port

pytestmark = pytest.mark.multiprocess

HOST_TO_B, B_ADDRESS = "10.213.80.1", "10.213.80.2"  # this host and host B, a /30 of the test's own
HOST_TO_INTRUDER, INTRUDER_ADDRESS = "10.213.81.1", "10.213.81.2"  # this host and the intruder's
INTRUDER = Path(__file__).with_name("intruder.py")
SECRET = "correct horse battery staple"  # the password of the user/password test


TLS = "transport/link/tls/"  # Zenoh's configuration keys of TLS links
USRPWD = "transport/auth/usrpwd/"


def tls_options(ca: Path, cert: Path, key: Path) -> list[str]:
    return ["--tls-ca", str(ca), "--tls-cert", str(cert), "--tls-key", str(key)]


def client_tls(ca: Path, cert: Path | None = None, key: Path | None = None) -> dict:
    """The Zenoh configuration of a peer that trusts ``ca`` and, given them, shows ``cert`` and ``key``."""
    shown = {} if cert is None else {TLS + "enable_mtls": True, TLS + "connect_certificate": str(cert),
                                     TLS + "connect_private_key": str(key)}
    return {TLS + "root_ca_certificate": str(ca), **shown}


def start_waiting_run(processes, summary: Path, *options: str):
    """A manager that spawned S1 and waits for S2; its process, the run id and S1's port (read from S1's command
    line: the worst case, an intruder that knows them), once it is clear that no secret is on that line."""
    manager = processes("run", "two_mass_damped", "--bus", "zenoh", "--external", "S2", "--summary", str(summary),
                        *options)
    read_until(manager.stderr, "waiting", 60)
    s1 = wait_for(lambda: [pid for pid in children_of(manager.pid) if " S1 " in cmdline(pid)], 30, "S1's process")
    line = cmdline(s1[0])
    assert SECRET not in line and "PRIVATE KEY" not in line, line
    return manager, line.split("--run-id ")[1].split()[0], line.split("--listen ")[1].split()[0].rpartition(":")[2]


def intrude(prefix: tuple[str, ...], endpoint: str, run_id: str, config: dict, publish: bool) -> dict:
    """What ``intruder.py`` found, run in the namespace ``prefix`` enters."""
    arguments = json.dumps({"endpoint": endpoint, "run_id": run_id, "config": config, "publish": publish})
    done = subprocess.run([*prefix, sys.executable, str(INTRUDER), arguments], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def attack(run_id: str, attempts: dict, member: tuple) -> tuple[dict, dict]:
    """Every attempt ``name: (prefix, endpoint, config)`` publishing its STOP and garbage, and a member's look
    (the same code with the run's credentials, publishing nothing), all at once; what each found."""
    with ThreadPoolExecutor(len(attempts) + 1) as pool:
        refused = {name: pool.submit(intrude, *attempt[:2], run_id, attempt[2], True)
                   for name, attempt in attempts.items()}
        looked = pool.submit(intrude, *member[:2], run_id, member[2], False)
        refused = {name: future.result() for name, future in refused.items()}
        found = looked.result()
    # the same code with credentials finds the run: a peer, its description, the manager's liveliness token
    assert found["peers"] >= 1, found
    assert [json.loads(run)["run_id"] for run in found["runs"]] == [run_id], found
    assert f"zencosim/{run_id}/manager/alive" in found["tokens"], found
    for name, got in refused.items():
        assert got.get("peers", 0) == 0, (name, got)
        for learned in ("runs", "queryables", "tokens", "heard"):
            assert not got.get(learned), (name, learned, got)
    return refused, found


def completes_with_the_in_process_digest(manager, remote, summary: Path) -> None:
    _, manager_err = manager.communicate(timeout=120)
    _, remote_err = remote.communicate(timeout=30)
    assert manager.returncode == 0, manager_err + remote_err
    assert remote.returncode == 0, remote_err
    assert json.loads(summary.read_text())["digest"] == summary_of("two_mass_damped")["digest"]


@pytest.fixture
def certificates(tmp_path):
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command to make certificates")
    certificate_authority(tmp_path, "run")
    certificate_authority(tmp_path, "rogue")
    return {"ca": tmp_path / "run-ca.pem",
            "a": certificate(tmp_path, "run", "host-a", ["127.0.0.1", HOST_TO_B, HOST_TO_INTRUDER]),
            "b": certificate(tmp_path, "run", "host-b", [B_ADDRESS]),
            "rogue": certificate(tmp_path, "rogue", "intruder", [INTRUDER_ADDRESS])}


@pytest.mark.timeout(240)
def test_an_intruder_without_credentials_cannot_find_read_or_stop_a_tls_run_that_completes(
        processes, network, certificates, tmp_path):
    host_b, intruder_ns = network.namespace("b"), network.namespace("x")
    network.link(None, HOST_TO_B, host_b, B_ADDRESS)
    network.link(None, HOST_TO_INTRUDER, intruder_ns, INTRUDER_ADDRESS)
    on_b, on_intruder = ("ip", "netns", "exec", host_b), ("ip", "netns", "exec", intruder_ns)
    ca = certificates["ca"]
    port = free_tcp_port()
    summary = tmp_path / "summary.json"
    manager, run_id, s1_port = start_waiting_run(processes, summary, "--listen", f"tls/0.0.0.0:{port}",
                                                 *tls_options(ca, *certificates["a"]))
    credentials = {  # an intruder may know the authority's certificate: it is no secret
        "plain tcp": ("tcp", {}),
        "tls without a certificate": ("tls", client_tls(ca)),
        "tls with another authority's certificate": ("tls", client_tls(ca, *certificates["rogue"])),
    }
    attempts = {(name, process): (on_intruder, f"{protocol}/{HOST_TO_INTRUDER}:{target_port}", config)
                for name, (protocol, config) in credentials.items()
                for process, target_port in (("manager", port), ("S1", s1_port))}
    refused, _ = attack(run_id, attempts, (on_b, f"tls/{HOST_TO_B}:{port}", client_tls(ca, *certificates["b"])))
    # what it still gets: the port answers, and TLS shows anyone the manager's certificate (its names, addresses)
    assert refused["tls without a certificate", "manager"]["certificate"] == "-----BEGIN CERTIFICATE-----"

    remote = processes("subsystem", "two_mass_damped", "S2", "--connect", f"tls/{HOST_TO_B}:{port}",
                       "--listen", f"tls/{B_ADDRESS}:0", *tls_options(ca, *certificates["b"]), prefix=on_b)
    completes_with_the_in_process_digest(manager, remote, summary)


@pytest.mark.timeout(240)
def test_on_loopback_a_process_without_the_password_cannot_find_read_or_stop_a_run_that_completes(
        processes, tmp_path):
    password = tmp_path / "password.txt"
    password.write_text(SECRET + "\n")
    credentials = ["--user", "runner", "--password-file", str(password)]
    port = free_tcp_port()
    summary = tmp_path / "summary.json"
    manager, run_id, s1_port = start_waiting_run(processes, summary, "--listen", f"tcp/127.0.0.1:{port}", *credentials)
    here = ()
    attempts = {(name, process): (here, f"tcp/127.0.0.1:{target_port}", config)
                for name, config in (("no password", {}),
                                     ("a wrong password", {USRPWD + "user": "runner", USRPWD + "password": "guess"}),
                                     ("another user", {USRPWD + "user": "root", USRPWD + "password": SECRET}))
                for process, target_port in (("manager", port), ("S1", s1_port))}
    attack(run_id, attempts, (here, f"tcp/127.0.0.1:{port}", {USRPWD + "user": "runner", USRPWD + "password": SECRET}))
    remote = processes("subsystem", "two_mass_damped", "S2", "--connect", f"tcp/127.0.0.1:{port}", *credentials)
    completes_with_the_in_process_digest(manager, remote, summary)


@pytest.mark.parametrize(("options", "expected"), [
    (["--tls-ca", "missing-ca.pem", "--tls-cert", "run-ca.pem", "--tls-key", "run-ca.key"],
     "--tls-ca missing-ca.pem: no such file"),
    (["--tls-ca", "run-ca.pem", "--tls-cert", "run-ca.key", "--tls-key", "run-ca.key"],
     "--tls-cert run-ca.key: expected a certificate in PEM format"),
    (["--tls-ca", "run-ca.pem", "--tls-cert", "run-ca.pem"], "--tls-ca, --tls-cert without --tls-key"),
    (["--tls-ca", "run-ca.pem", "--tls-cert", "run-ca.pem", "--tls-key", "run-ca.key", "--listen", "tcp/127.0.0.1:0"],
     "--listen tcp/127.0.0.1:0: with --tls-ca/--tls-cert/--tls-key every endpoint is tls/HOST:PORT"),
    (["--zenoh-config", "syntax.json5"], "--zenoh-config syntax.json5: line 1, column 17: expected identifier"),
    (["--zenoh-config", "unknown.json5"],
     "--zenoh-config unknown.json5: line 1, column 16: unknown field `nosuch`"),
    (["--zenoh-config", "type.json5"],
     '--zenoh-config type.json5: line 1, column 44: invalid type: string "yes", expected a boolean'),
    (["--zenoh-config", "names-missing-key.json5", "--listen", "tls/127.0.0.1:0"],
     "cannot open the Zenoh session listening on tls/127.0.0.1:…: Cannot create a new TLS listener on 127.0.0.1:…"
     "Missing TLS private key"),
    (["--user", "runner", "--password-file", "missing.txt"], "--password-file missing.txt: cannot read it"),
    (["--user", "run:ner", "--password-file", "password.txt"], "--user 'run:ner': expected a non-empty name"),
    (["--user", "runner"], "--user and --password-file go together"),
    (["--set", "manager.zenoh_config=unknown.json5"],
     "manager.zenoh_config = unknown.json5: line 1, column 16: unknown field `nosuch`"),
])
def test_bad_credentials_and_zenoh_configuration_files_are_named_with_exit_status_2(tmp_path, options, expected):
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command to make certificates")
    certificate_authority(tmp_path, "run")
    (tmp_path / "password.txt").write_text("s3cret\n")
    (tmp_path / "syntax.json5").write_text('{ mode: "peer", ')
    (tmp_path / "unknown.json5").write_text("{ transport: { nosuch: 1 } }")
    (tmp_path / "type.json5").write_text('{ transport: { link: { tls: { enable_mtls: "yes" } } } }')
    (tmp_path / "names-missing-key.json5").write_text(
        '{ transport: { link: { tls: { root_ca_certificate: "run-ca.pem", listen_certificate: "run-ca.pem" } } } }')
    done = subprocess.run([sys.executable, "-m", "zencosim", "run", "two_mass_damped", "--bus", "zenoh", *options],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    message = " ".join(done.stderr.split())
    assert re.search(".*".join(map(re.escape, expected.split("…"))), message), done.stderr  # … stands for a port


@pytest.mark.timeout(240)
def test_tls_set_up_by_a_zenoh_configuration_file_alone_runs_with_the_in_process_digest(tmp_path):
    # anything Zenoh supports goes through --zenoh-config (here the scene's manager.zenoh_config): the
    # spawned subsystems get the file and listen with the manager's protocol
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command to make certificates")
    certificate_authority(tmp_path, "run")
    cert, key = certificate(tmp_path, "run", "host", ["127.0.0.1"])
    tls = {"root_ca_certificate": "run-ca.pem", "enable_mtls": True, "listen_certificate": cert.name,
           "listen_private_key": key.name, "connect_certificate": cert.name, "connect_private_key": key.name}
    (tmp_path / "zenoh.json5").write_text(json.dumps({"transport": {"link": {"tls": tls}}}))
    summary = tmp_path / "summary.json"
    done = subprocess.run([sys.executable, "-m", "zencosim", "run", "two_mass_damped", "--bus", "zenoh", "--quiet",
                           "--set", "manager.zenoh_config=zenoh.json5", "--listen", "tls/127.0.0.1:0",
                           "--summary", str(summary)], cwd=tmp_path, capture_output=True, text=True, timeout=200)
    assert done.returncode == 0, done.stderr
    assert json.loads(summary.read_text())["digest"] == summary_of("two_mass_damped")["digest"]


def test_the_options_handed_to_other_processes_are_paths_and_placeholders_never_secrets(tmp_path):
    password = tmp_path / "password.txt"
    password.write_text(SECRET + "\n")
    security = ZenohSecurity(user="runner", password_file=password).checked()
    spawned, by_hand = security.arguments(), security.arguments(elsewhere=True)
    assert spawned == ["--user", "runner", "--password-file", str(password.resolve())]
    assert by_hand == ["--user", "runner", "--password-file", "<the password file>"]
    assert security.password() == SECRET and SECRET not in " ".join(spawned + by_hand)
