"""``zencosim subsystem``: serve one subsystem of a scene in this process, for runs across hosts."""
from __future__ import annotations

import argparse

from zencosim.cli.console import add_scene_arguments, examples
from zencosim.cli.credentials import add_security_arguments, security_options
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.scene.load import load_scene


def cmd_subsystem(args: argparse.Namespace) -> int:
    from zencosim.subsystems.process.host import serve
    scene = load_scene(args.scene, args.overrides)
    security = security_options(args, scene)
    listen = args.listen or f"{security.protocol}/127.0.0.1:0"
    security.check_endpoints("--connect", args.connect)
    security.check_endpoints("--listen", [listen])
    return serve(scene, args.name, args.connect, args.run_id, ZenohOptions(not args.no_lowlatency, security),
                 args.wait, listen)


def add_parsers(commands) -> None:
    sub = commands.add_parser(
        "subsystem", help="serve one subsystem of a scene over Zenoh (for runs across hosts)",
        **examples("zencosim run two_mass_damped --bus zenoh --listen tcp/0.0.0.0:7447 --external S2   # on host A",
                   "zencosim subsystem two_mass_damped S2 --connect tcp/HOST_A:7447                   # on host B",
                   "zencosim subsystem two_mass_damped S2 --connect tls/HOST_A:7447 --tls-ca ca.pem --tls-cert b.pem "
                   "--tls-key b.key   # mutual TLS (docs/security.md)"))
    add_scene_arguments(sub)
    sub.add_argument("name", help="the subsystem to serve")
    sub.add_argument("--connect", action="append", required=True, metavar="ENDPOINT",
                     help="Zenoh endpoint of the manager, e.g. tcp/192.0.2.10:7447")
    sub.add_argument("--listen", metavar="ENDPOINT",
                     help="where the other processes of the run reach this one (default: a free loopback port; "
                          "across hosts this host's address, e.g. tcp/192.0.2.11:7448)")
    sub.add_argument("--run-id", help="the run to join (default: the one run that waits for this subsystem)")
    sub.add_argument("--wait", type=float, default=30.0, metavar="SECONDS", help="how long to look for the run")
    sub.add_argument("--no-lowlatency", action="store_true", help="use Zenoh's default transport instead of lowlatency")
    add_security_arguments(sub)
    sub.set_defaults(handler=cmd_subsystem)
