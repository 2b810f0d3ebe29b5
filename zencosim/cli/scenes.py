"""``zencosim scenes`` and ``zencosim check``: the bundled scenes, and what a scene builds."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

import tomli_w
from rich.markup import escape
from rich.table import Table

from zencosim.cli.console import add_scene_arguments, examples, out, say
from zencosim.manager.assembly import plan_scene
from zencosim.manager.results.output_files import check_output_file
from zencosim.manager.scene.load import SceneError, bundled_scene_names, load_scene, scene_from_text
from zencosim.manager.scheme.energy_step import step_bounds
from zencosim.subsystems.params import Problem
from zencosim.subsystems.ports import Port


def cmd_scenes(args: argparse.Namespace) -> int:
    table = Table(title="bundled scenes")
    table.add_column("scene")
    table.add_column("description")
    for name in bundled_scene_names():
        table.add_row(name, load_scene(name).description)
    out.print(table)
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene, args.overrides)
    plan, _ = plan_scene(scene)
    out.print(f"[bold]scene {escape(scene.name)}[/]: valid — {escape(scene.description)}")
    for note in scene.notes:
        out.print(escape(f"  mapped: {note}"), highlight=False)
    bonds = [f"{c.name}" + (f" ({c.settings.domain})" if c.settings.domain != "translational" else "")
             for c in scene.couplings.values() if c.kind == "force_displacement"]
    control = scene.manager.energy_control  # read whenever given; used with step_control = "energy" only
    steps = (f"{plan.n_ticks} macro-steps of {scene.manager.macro_step:g} s"
             if scene.manager.step_control != "energy" else
             "energy-controlled macro-steps of {:g} … {:g} s".format(
                 *(ns * 1e-9 for ns in step_bounds(control, scene.manager.macro_step_ns)[::2]))
             + f" (whole multiples of {scene.manager.macro_step:g} s)")
    out.print(f"{steps}, scheme {scene.manager.scheme}, "
              f"extrapolation order {scene.manager.extrapolation}; bonds: {', '.join(bonds) or 'none'}")
    signals = [c for c in scene.couplings.values() if c.kind == "signal"]
    if signals:
        out.print(escape("signal connections: " + ", ".join(
            f"{c.name} ({c.settings.output} -> {c.settings.input}"
            + (f", × {c.settings.factor:g} + {c.settings.offset:g}" if (c.settings.factor, c.settings.offset) != (1, 0)
               else "")
            + (f", order {c.settings.extrapolation}" if c.settings.extrapolation is not None else "") + ")"
            for c in signals)))
    if scene.manager.implicit is not None:
        joints = ", ".join(f"{c.name} ({c.settings.decomposition})" for c in scene.couplings.values())
        out.print(escape(f"implicit coupling: {scene.manager.implicit.coupling_method()}, k = {scene.manager.extrapolation}, "
                         f"up to {scene.manager.implicit.max_iterations} corrector run(s); joint {joints}"))
    for sub in plan.subsystems:
        settings = scene.subsystems[sub.name].settings
        out.print(f"[bold]{sub.name}[/]: {settings.model}, {settings.integrator}, micro-step {settings.micro_step:g} s, "
                  f"communication step {sub.ratio * scene.manager.macro_step:g} s")
        out.print(escape(f"  inputs:  {', '.join(f'{p.name} [{p.unit}]' for p in sub.inputs) or 'none'}"))
        out.print(escape("  outputs: " + ", ".join(f"{p.name} [{p.unit}]" + _feedthrough_mark(p) for p in sub.outputs)))
        stated = getattr(scene.subsystems[sub.name].spec, "feedthrough", None)
        if stated is not None:
            out.print(escape(f"  feedthrough (subsystems.{sub.name}.feedthrough): " + (", ".join(
                f"{output} <- {', '.join(inputs) or 'none'}" for output, inputs in stated.items())
                or "no output") + ("; the other outputs: none" if stated else "")))
        out.print(escape(f"  effects: {', '.join(sub.effects) or 'none'}"))
        for key, unit in scene.replaced_units.items():
            if key.startswith(f"{sub.name}."):
                out.print(escape(f"  unit: {key.removeprefix(sub.name + '.')} [{unit['scene']}], the scene's, replaces "
                                 f"the declared [{unit['declared']}]"), highlight=False)
    return 0


def _feedthrough_mark(port: Port) -> str:
    """How ``check`` marks an output's direct feedthrough: declared, or only FMI's default (``Port.undeclared``)."""
    if port.undeclared:
        return " (feedthrough undeclared: every input)"
    return " (feedthrough)" if port.feedthrough else ""


def cmd_convert(args: argparse.Namespace) -> int:
    """A system description (OSP XML, SSP) as a TOML scene, its FMU paths relative to the new file.

    The scene is checked before it is written, as ``zencosim check`` checks it (loaded, then planned: the
    memory of its run, the FMUs' ports): one that would not load is not written (an existing file is left as
    it was); the problems are reported as ``check`` reports the system description's, exit status 2."""
    from zencosim.manager.scene.imports import import_system
    target = check_output_file(args.to, "scene", (".toml",))
    document, notes = import_system(Path(args.system), args.duration)
    source_directory = Path(args.system).resolve().parent
    for table in document["subsystems"].values():
        if "fmu" in table:
            table["fmu"] = Path(os.path.relpath(source_directory / table["fmu"], target.resolve().parent)).as_posix()
    header = "".join(f"# {line}\n" for line in [f"converted from {args.system} by zencosim convert", *notes])
    text = header + "\n" + tomli_w.dumps(document)
    try:
        plan_scene(scene_from_text(text, str(target)))  # paths resolve from the target's directory
    except SceneError as error:
        hint = "; --duration SECONDS sets manager.duration" if any(
            p.key == "manager.duration" for p in error.problems) else ""
        raise SceneError(args.system, [*error.problems, Problem(
            "--to", f"{args.to} not written: the scene converted from this file would not load (zencosim check "
                    f"{args.system} shows the same){hint}")]) from None
    target.write_text(text)
    say(f"wrote {target}")
    return 0


def add_parsers(commands) -> None:
    commands.add_parser("scenes", help="list the bundled scenes").set_defaults(handler=cmd_scenes)
    check = commands.add_parser("check", help="validate a scene and show what it builds",
                                **examples("zencosim check four_mass",
                                           "zencosim check my_scene.toml --set manager.macro_step=0.002"))
    add_scene_arguments(check)
    check.set_defaults(handler=cmd_check)

    convert = commands.add_parser(
        "convert", help="write an OSP system structure (.xml) or an SSP system (.ssp, .ssd) as a TOML scene",
        **examples("zencosim convert OspSystemStructure.xml --to two_mass.toml",
                   "zencosim check OspSystemStructure.xml      # what it maps to, without writing it"))
    convert.add_argument("system", help="an OSP system structure (.xml) or an SSP system (.ssp, .ssd)")
    convert.add_argument("--to", required=True, metavar="SCENE.toml", help="the scene to write")
    convert.add_argument("--duration", type=float, metavar="SECONDS",
                         help="the simulated time (default: the file's end time, else 10 s)")
    convert.set_defaults(handler=cmd_convert)
