"""``zencosim check-model`` and ``zencosim examples``: bring your own model, and examples of doing so."""
from __future__ import annotations

import argparse
from pathlib import Path

from zencosim.cli.console import UsageError, examples, say
from zencosim.manager.scene.overrides import parse_override


def cmd_check_model(args: argparse.Namespace) -> int:
    from zencosim.subsystems.models.conformance import UnusableModel, check_component
    start = {}
    for text in args.start:
        try:
            (name, *rest), value = parse_override(text)
        except ValueError as error:
            raise UsageError(str(error).replace("--set", "--start")) from None
        if rest or not isinstance(value, (int, float)) or isinstance(value, bool):
            raise UsageError(f"--start {text}: expected NAME=NUMBER")
        start[name] = value
    units = {}
    for text in args.unit:
        name, _, unit = text.partition("=")
        if not name.strip() or not unit.strip():
            raise UsageError(f"--unit {text}: expected NAME=UNIT (an SI unit, e.g. fc=N)")
        units[name.strip()] = unit.strip()
    try:
        problems = check_component(args.model, start, units=units)
    except UnusableModel as error:
        raise UsageError(str(error)) from None
    for problem in problems:
        say(f"FAILED: {problem}")
    if not problems:
        say(f"{args.model}: conforms (SI units, finite outputs, two instances identical, feedthrough declared, "
            "save and restore exact)")
    return 1 if problems else 0


def cmd_examples(args: argparse.Namespace) -> int:
    from zencosim.examples.write import write_examples
    directory = Path(args.directory)
    for scene in write_examples(directory):
        say(f"wrote {scene}")
    say(f"run one with: zencosim run {directory / 'two_mass_damped_fmu.toml'}")
    return 0


def add_parsers(commands) -> None:
    check = commands.add_parser(
        "check-model", help="check a model of your own (a Python class or an FMU) as the built-in ones are checked",
        **examples("zencosim check-model mypackage.oscillator:Oscillator",
                   "zencosim check-model examples/oscillator_fmi2.fmu --start k=10"))
    check.add_argument("model", help="package.module:Class, a name registered in the entry points zencosim.models, "
                                     "or a path to an FMU")
    check.add_argument("--start", action="append", default=[], metavar="NAME=VALUE",
                       help="a parameter or start value for the check (repeatable)")
    check.add_argument("--unit", action="append", default=[], metavar="NAME=UNIT",
                       help="the SI unit of a variable that declares none, as a scene's units table gives it "
                            "(repeatable)")
    check.set_defaults(handler=cmd_check_model)

    example = commands.add_parser(
        "examples", help="write the example scenes (FMUs built from C sources here, a Python model) into a directory",
        **examples("zencosim examples my_examples && zencosim run my_examples/two_mass_damped_fmu.toml"))
    example.add_argument("directory", help="where to write them (created if needed)")
    example.set_defaults(handler=cmd_examples)
