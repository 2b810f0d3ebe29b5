"""The options that say who may join a run over Zenoh (``run``, ``subsystem``, ``router``; docs/security.md)."""
from __future__ import annotations

import argparse
from pathlib import Path

from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.scene.load import Scene

OPTIONS = ("--zenoh-config", "--tls-ca", "--tls-cert", "--tls-key", "--user", "--password-file")


def add_security_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("who may join the run (docs/security.md)")
    group.add_argument("--zenoh-config", type=Path, metavar="FILE",
                       help="a Zenoh JSON5 configuration file, merged under the run's own settings (default: the "
                            "scene's manager.zenoh_config)")
    group.add_argument("--tls-ca", type=Path, metavar="FILE",
                       help="mutual TLS: the certificate authority (PEM) every process's certificate is signed by")
    group.add_argument("--tls-cert", type=Path, metavar="FILE", help="mutual TLS: this process's certificate (PEM)")
    group.add_argument("--tls-key", type=Path, metavar="FILE", help="mutual TLS: its private key (PEM)")
    group.add_argument("--user", metavar="NAME", help="user/password authentication: the run's user name")
    group.add_argument("--password-file", type=Path, metavar="FILE",
                       help="a file whose first line is the password (never on the command line)")


def security_options(args: argparse.Namespace, scene: Scene | None = None) -> ZenohSecurity:
    """The checked settings (absolute paths); SecurityError naming the option and file that cannot be used.
    The configuration file is ``--zenoh-config``, else the ``scene``'s ``manager.zenoh_config``."""
    given = ZenohSecurity(args.zenoh_config, args.tls_ca, args.tls_cert, args.tls_key, args.user, args.password_file)
    return given.checked() if scene is None else given.checked_with_scene(scene.manager.zenoh_config, scene.path)


def given_security_options(args: argparse.Namespace) -> list[str]:
    return [option for option in OPTIONS if getattr(args, option[2:].replace("-", "_")) is not None]
