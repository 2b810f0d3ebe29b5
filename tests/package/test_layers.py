"""The layers of zencosim, as the folders show them: a module imports only from its own layer and those
below it, and the models and the analysis know nothing of Zenoh, MCAP or Rerun (DESIGN.md).

Read from the source with ``ast`` (imports inside functions count too), so a violation is found without
running the code that contains it.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.package.conftest import layer_folders

# lowest first; a module belongs to the layer of its longest matching prefix
LAYERS = (
    ("optional parts", ("zencosim.extras", "zencosim.scenes", "zencosim.versions")),
    ("design-time maths", ("zencosim.compensation",)),
    ("models", ("zencosim.subsystems.params", "zencosim.subsystems.ports", "zencosim.subsystems.inputs",
                "zencosim.subsystems.units", "zencosim.subsystems.sketch",
                "zencosim.subsystems.effects", "zencosim.subsystems.integrators", "zencosim.subsystems.models",
                "zencosim.subsystems.straight_line", "zencosim.subsystems.native",
                "zencosim.subsystems.subsystem")),
    ("scene", ("zencosim.manager.scene",)),
    ("plan", ("zencosim.manager.plan",)),
    ("wire", ("zencosim.manager.wire",)),
    ("scheme", ("zencosim.manager.scheme",)),
    ("analysis", ("zencosim.manager.analysis",)),
    ("assembly", ("zencosim.manager.assembly",)),
    ("bus", ("zencosim.manager.bus", "zencosim.subsystems.process")),
    ("results", ("zencosim.manager.results",)),
    ("record", ("zencosim.recordings",)),
    ("run", ("zencosim.manager.run", "zencosim.manager.realtime_probe")),
    ("study", ("zencosim.manager.study",)),
    ("entry points", ("zencosim.api", "zencosim.cli", "zencosim.__main__", "zencosim.examples")),
)
PACKAGE_ROOTS = tuple(folder for folder in layer_folders() if folder != "scenes")  # the folders with modules
NO_TRANSPORT = ("design-time maths", "models")  # layers that must not import these
TRANSPORT = ("zenoh", "mcap", "rerun")


def _modules() -> dict[str, Path]:
    found = {}
    for path in (REPO / "zencosim").rglob("*.py"):
        found[".".join(("zencosim", *path.relative_to(REPO / "zencosim").with_suffix("").parts))] = path
    for root in PACKAGE_ROOTS:
        for path in (REPO / root).rglob("*.py"):
            found[".".join(("zencosim", *path.relative_to(REPO).with_suffix("").parts))] = path
    return {name.removesuffix(".__init__"): path for name, path in found.items()}


MODULES = _modules()


def layer_of(module: str) -> int | None:
    """Index of ``module``'s layer; None for the package ``zencosim`` and the layer folders' ``__init__``."""
    best = None
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and (best is None or len(prefix) > best[1]):
                best = (index, len(prefix))
    return None if best is None else best[0]


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every absolute import in the file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}:{node.lineno}: a relative import; write zencosim.… in full"
            found.append((node.lineno, node.module))
            found += [(node.lineno, f"{node.module}.{alias.name}") for alias in node.names
                      if f"{node.module}.{alias.name}" in MODULES]
    return found


def test_every_module_has_a_layer():
    unplaced = [name for name in MODULES if layer_of(name) is None and name.count(".") > 1]
    assert unplaced == []


@pytest.mark.parametrize("module", sorted(MODULES))
def test_a_module_imports_nothing_from_a_layer_above_its_own(module):
    own = layer_of(module)
    path = MODULES[module]
    for line, imported in imports(path):
        top = imported.split(".")[0]
        assert top not in PACKAGE_ROOTS + ("scenes",), (
            f"{path}:{line}: imports {imported}; zencosim's modules are imported as zencosim.{imported}")
        if own is not None and top in TRANSPORT:
            assert LAYERS[own][0] not in NO_TRANSPORT, f"{path}:{line}: the {LAYERS[own][0]} layer imports {imported}"
        if own is None or top != "zencosim" or imported == "zencosim":
            continue
        theirs = layer_of(imported)
        assert theirs is not None and theirs <= own, (
            f"{path}:{line}: {module} ({LAYERS[own][0]}) imports {imported} "
            f"({LAYERS[theirs][0] if theirs is not None else 'no layer'}), a layer above it")
