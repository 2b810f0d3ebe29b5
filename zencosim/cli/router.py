"""``zencosim router``: a Zenoh router that hosts of a run reach when they cannot reach each other."""
from __future__ import annotations

import argparse

from zencosim.cli.console import examples, warn
from zencosim.cli.credentials import add_security_arguments, security_options
from zencosim.manager.bus.router import serve_router
from zencosim.manager.bus.zenoh_session import ZenohOptions

DEFAULT_LISTEN = "tcp/0.0.0.0:7447"  # tls/ with certificates


def cmd_router(args: argparse.Namespace) -> int:
    security = security_options(args)
    listen = args.listen or [DEFAULT_LISTEN.replace("tcp/", f"{security.protocol}/")]
    security.check_endpoints("--listen", listen)
    security.check_endpoints("--connect", args.connect)
    return serve_router(listen, args.connect, ZenohOptions(not args.no_lowlatency, security), warn)


def add_parsers(commands) -> None:
    sub = commands.add_parser(
        "router", help="run a Zenoh router, for hosts of a run that reach each other only through it",
        **examples("zencosim router --listen tcp/0.0.0.0:7447                                          # host R",
                   "zencosim run two_mass_damped --bus zenoh --connect tcp/R:7447 --external S2        # host A",
                   "zencosim subsystem two_mass_damped S2 --connect tcp/R:7447                         # host B",
                   "zencosim router --tls-ca ca.pem --tls-cert r.pem --tls-key r.key    # tls/0.0.0.0:7447, mutual TLS"))
    sub.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                     help=f"where the run's processes reach the router (repeatable; default {DEFAULT_LISTEN})")
    sub.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                     help="another router to link with (repeatable), for runs across several networks")
    sub.add_argument("--no-lowlatency", action="store_true",
                     help="use Zenoh's default transport (the run's processes must use it too)")
    add_security_arguments(sub)
    sub.set_defaults(handler=cmd_router)
