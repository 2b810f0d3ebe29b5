"""Who may join a run over Zenoh: mutual TLS, user/password authentication, access control (docs/security.md).

Every process of a run (manager, subsystem processes, ``zencosim router``) takes the same
:class:`ZenohSecurity`: file paths only, so that the manager hands them to the processes it spawns on
their command line without putting a secret there (a password stays in its file, a private key in its
own). With certificates, every link is ``tls/`` with mutual authentication against one certificate
authority, and an access-control list lets only TLS links publish, subscribe, query or declare tokens
under ``zencosim/**``: a peer without a certificate of that authority cannot open a session at all,
so it can neither find a run nor read or disturb it. A user's Zenoh configuration file
(``--zenoh-config``) is the base under the run's own settings, for anything else Zenoh supports.
"""
from __future__ import annotations

import atexit
import json
import os
import re
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import zenoh

# every message kind Zenoh's access control knows (zenoh 1.x); a run's processes need each of them
ACL_MESSAGES = ("put", "delete", "declare_subscriber", "query", "declare_queryable", "reply", "liveliness_token",
                "declare_liveliness_subscriber", "liveliness_query")


class SecurityError(ValueError):
    """A credential file or Zenoh configuration file that cannot be used (exit status 2)."""


def zenoh_reason(error: Exception) -> str:
    """A Zenoh error without its Rust source location: ``line L, column C: what`` where Zenoh says where."""
    text = re.sub(r"\s+at /\S+\.rs:\d+\.?", "", str(error).strip())  # where in Zenoh's sources
    found = re.search(r'msg: "(.*?)", location: Some\(Location \{ line: (\d+), column: (\d+) \}\)', text)
    if found:
        what, line, column = found.groups()
        return f"line {line}, column {column}: {what.replace(chr(92) + chr(34), chr(34))}"
    found = re.search(r"--> (\d+):(\d+).*= (.*)$", text, re.S)
    if found:
        line, column, what = found.groups()
        return f"line {line}, column {column}: {what.strip()}"
    return text


PEM_MARKERS = {"certificate": "-----BEGIN CERTIFICATE-----", "private key": "PRIVATE KEY-----"}


def _pem(option: str, path: Path, holds: str) -> Path:
    """``path``, absolute, once it is a readable PEM file that holds a ``certificate`` or a ``private key``."""
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        raise SecurityError(f"{option} {path}: no such file") from None
    except OSError as error:
        raise SecurityError(f"{option} {path}: cannot read it ({error.strerror})") from None
    if PEM_MARKERS[holds] not in text:
        raise SecurityError(f"{option} {path}: expected a {holds} in PEM format (a '{PEM_MARKERS[holds]}' line)")
    return path.resolve()


@dataclass(frozen=True)
class ZenohSecurity:
    """The credentials of one process of a run, and a Zenoh configuration file to start from."""

    config_file: Path | None = None  # a Zenoh JSON5 configuration, merged under the run's own settings
    tls_ca: Path | None = None  # the certificate authority every process's certificate is checked against
    tls_cert: Path | None = None  # this process's certificate (PEM), signed by tls_ca
    tls_key: Path | None = None  # its private key (PEM)
    user: str | None = None  # user/password authentication: the run's user name
    password_file: Path | None = None  # a file holding its password (one line)

    @property
    def tls(self) -> bool:
        return self.tls_ca is not None

    @property
    def protocol(self) -> str:
        """The link protocol of the run's endpoints."""
        return "tls" if self.tls else "tcp"

    def checked(self, config_origin: str = "--zenoh-config") -> "ZenohSecurity":
        """The same settings with absolute paths, once every file is usable; else SecurityError naming it (the
        configuration file as ``config_origin`` says where it was given)."""
        tls = {"--tls-ca": self.tls_ca, "--tls-cert": self.tls_cert, "--tls-key": self.tls_key}
        given = [option for option, path in tls.items() if path is not None]
        if given and len(given) < 3:
            missing = ", ".join(option for option in tls if option not in given)
            raise SecurityError(f"{', '.join(given)} without {missing}: mutual TLS needs the authority's certificate, "
                                "this process's certificate and its private key")
        if (self.user is None) != (self.password_file is None):
            raise SecurityError("--user and --password-file go together (user/password authentication needs both)")
        if self.user is not None and (not self.user or ":" in self.user or not self.user.isprintable()):
            raise SecurityError(f"--user {self.user!r}: expected a non-empty name without ':' or control characters")
        self.base_config(config_origin)  # its errors now (naming the file as given), not in a spawned process
        if self.password_file is not None:
            self.password()
        config_file, password_file = (None if path is None else path.resolve()
                                      for path in (self.config_file, self.password_file))
        return ZenohSecurity(
            config_file, *(None if path is None else _pem(option, path, holds) for (option, path), holds in
                           zip(tls.items(), ("certificate", "certificate", "private key"))),
            self.user, password_file)

    def checked_with_scene(self, scene_config: str, scene_path: str) -> "ZenohSecurity":
        """:meth:`checked`, with the scene's ``manager.zenoh_config`` (``scene_config``, "" for none) when no
        configuration file is given."""
        if self.config_file is None and scene_config:
            return replace(self, config_file=Path(scene_config)).checked(f"scene {scene_path}: manager.zenoh_config =")
        return self.checked()

    def base_config(self, origin: str = "--zenoh-config") -> zenoh.Config:
        """The user's Zenoh configuration file, or an empty configuration."""
        path = self.config_file
        if path is None:
            return zenoh.Config()
        if not path.is_file():
            raise SecurityError(f"{origin} {path}: no such file")
        try:
            return zenoh.Config.from_file(str(path))
        except zenoh.ZError as error:
            raise SecurityError(f"{origin} {path}: {zenoh_reason(error)}") from None

    def password(self) -> str:
        """The first line of the password file."""
        path = self.password_file
        try:
            lines = path.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as error:
            raise SecurityError(f"--password-file {path}: cannot read it ({getattr(error, 'strerror', error)})") from None
        if not lines or not lines[0]:
            raise SecurityError(f"--password-file {path}: empty; expected the password on its first line")
        return lines[0]

    def apply(self, config: zenoh.Config) -> None:
        """Add the credentials to a session's configuration, and access control unless the user's file has its own."""
        if self.tls:
            tls = {"root_ca_certificate": str(self.tls_ca), "enable_mtls": True,
                   "listen_certificate": str(self.tls_cert), "listen_private_key": str(self.tls_key),
                   "connect_certificate": str(self.tls_cert), "connect_private_key": str(self.tls_key)}
            for name, value in tls.items():
                config.insert_json5(f"transport/link/tls/{name}", json.dumps(value))
        if self.user is not None:
            password = self.password()
            usrpwd = {"user": self.user, "password": password,
                      "dictionary_file": _dictionary_file(f"{self.user}:{password}\n")}
            config.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
        if self.tls and not json.loads(config.get_json("access_control/enabled")):
            config.insert_json5("access_control", json.dumps(run_access_control()))

    def arguments(self, elsewhere: bool = False) -> list[str]:
        """The ``zencosim`` options that give a spawned process the same settings (paths and a user name only);
        ``elsewhere``: for a process started by hand on another host, which has files of its own (placeholders)."""
        options = {"--zenoh-config": (self.config_file, "<its Zenoh configuration>"),
                   "--tls-ca": (self.tls_ca, "<the authority's certificate>"),
                   "--tls-cert": (self.tls_cert, "<its certificate>"), "--tls-key": (self.tls_key, "<its key>"),
                   "--user": (self.user, self.user), "--password-file": (self.password_file, "<the password file>")}
        return [part for option, (value, placeholder) in options.items() if value is not None
                for part in (option, placeholder if elsewhere else str(value))]

    def check_endpoints(self, option: str, endpoints: list[str]) -> None:
        """With certificates, every endpoint of the run is a TLS one (a ``tcp/`` link would bypass them)."""
        if self.tls:
            plain = [endpoint for endpoint in endpoints if not endpoint.startswith("tls/")]
            if plain:
                raise SecurityError(f"{option} {plain[0]}: with --tls-ca/--tls-cert/--tls-key every endpoint is "
                                    f"tls/HOST:PORT (e.g. tls/{plain[0].split('/', 1)[-1]})")


def run_access_control() -> dict:
    """Zenoh access control for a TLS run: under ``zencosim/**`` only links authenticated by mutual TLS may send
    or receive anything (a plain link a configuration file adds gets nothing and can publish nothing there);
    everything else is denied."""
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [{"id": "zencosim-run", "messages": list(ACL_MESSAGES), "flows": ["ingress", "egress"],
                   "permission": "allow", "key_exprs": ["zencosim/**"]}],
        "subjects": [{"id": "tls-links", "link_protocols": ["tls"]}],
        "policies": [{"rules": ["zencosim-run"], "subjects": ["tls-links"]}],
    }


_DICTIONARIES: list[Path] = []  # written for sessions not opened yet


def _dictionary_file(content: str) -> str:
    """A private file (mode 0600) with Zenoh's user/password dictionary, until the session that reads it has opened
    (:func:`remove_dictionaries`), or this process exits."""
    handle, path = tempfile.mkstemp(prefix="zencosim-usrpwd-")
    with os.fdopen(handle, "w") as file:
        file.write(content)
    _DICTIONARIES.append(Path(path))
    atexit.register(Path(path).unlink, missing_ok=True)
    return path


def remove_dictionaries() -> None:
    """Remove the dictionary files written so far: Zenoh reads them when a session opens, not later."""
    while _DICTIONARIES:
        _DICTIONARIES.pop().unlink(missing_ok=True)
