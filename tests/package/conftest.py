"""What the packaging tests read from the repository's own packaging files."""
from __future__ import annotations

import ast

from tests.conftest import REPO


def layer_folders() -> tuple[str, ...]:
    """The repository folders that setup.py installs as ``zencosim.<folder>``."""
    for node in ast.walk(ast.parse((REPO / "setup.py").read_text())):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", None) == "LAYER_FOLDERS":
            return tuple(ast.literal_eval(node.value))
    raise AssertionError("setup.py defines no LAYER_FOLDERS")
