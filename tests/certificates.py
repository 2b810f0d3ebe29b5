"""Certificates for tests and benchmarks of runs over mutual TLS, made with the ``openssl`` command.

(The ``cryptography`` package is not a dependency of zencosim; the command is on every machine that has
OpenSSL.)
"""
from __future__ import annotations

import subprocess
from pathlib import Path


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, text=True, timeout=60)


def certificate_authority(directory: Path, name: str) -> None:
    """``NAME-ca.pem`` and ``NAME-ca.key``: a self-signed certificate authority (EC P-256)."""
    _openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-days", "2",
             "-keyout", f"{name}-ca.key", "-out", f"{name}-ca.pem", "-subj", f"/CN={name} test authority", cwd=directory)


def certificate(directory: Path, authority: str, name: str, addresses: list[str]) -> tuple[Path, Path]:
    """``NAME.pem`` signed by ``authority``, valid for the IP ``addresses`` (Zenoh checks the name it connects to),
    and its key ``NAME.key``."""
    _openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-keyout", f"{name}.key",
             "-out", f"{name}.csr", "-subj", f"/CN={name}", cwd=directory)
    (directory / f"{name}.ext").write_text(f"subjectAltName={','.join(f'IP:{a}' for a in addresses)}\n"
                                           "extendedKeyUsage=serverAuth,clientAuth\n")
    _openssl("x509", "-req", "-in", f"{name}.csr", "-CA", f"{authority}-ca.pem", "-CAkey", f"{authority}-ca.key",
             "-CAcreateserial", "-days", "2", "-out", f"{name}.pem", "-extfile", f"{name}.ext", cwd=directory)
    return directory / f"{name}.pem", directory / f"{name}.key"
