"""``zencosim examples DIR``: the example scenes with their FMUs built on this machine.

The FMUs are compiled from the C sources in ``zencosim/examples/fmus`` (gcc and fmpy's FMI headers);
the scenes refer to them by paths relative to the scene files, so the directory can be moved whole.
"""
from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

from zencosim.extras import require

FMUS = {  # file name -> (FMI version, interfaces)
    "oscillator_fmi2.fmu": (2, ("cs", "me")),
    "oscillator_fmi3.fmu": (3, ("cs",)),
}


def example_scenes() -> list[str]:
    """File names of the example scenes."""
    return sorted(p.name for p in resources.files("zencosim.examples").joinpath("scenes").iterdir()
                  if p.name.endswith(".toml"))


def write_examples(directory: Path) -> list[Path]:
    """Build the example FMUs into ``directory`` (created if needed) and copy the example scenes beside
    them; return the scenes. Needs fmpy (``zencosim[fmu]``) and gcc."""
    require("fmu", "building the example FMUs")
    if shutil.which("gcc") is None:
        raise RuntimeError("building the example FMUs needs a C compiler: gcc is not on the PATH")
    from zencosim.examples.fmus.build import build_fmu
    directory.mkdir(parents=True, exist_ok=True)
    for name, (version, interfaces) in FMUS.items():
        build_fmu(directory / name, version, interfaces)
    scenes = resources.files("zencosim.examples").joinpath("scenes")
    written = []
    for name in example_scenes():
        target = directory / name
        target.write_text(scenes.joinpath(name).read_text())
        written.append(target)
    return written
