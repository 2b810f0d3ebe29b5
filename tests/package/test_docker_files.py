"""The container image installs the same package as the wheel: its Dockerfile copies every file and folder
the install reads (no container engine runs here, so the build itself is not tried)."""
from __future__ import annotations

from tests.conftest import REPO
from tests.package.conftest import layer_folders


def test_the_dockerfile_copies_everything_the_install_needs():
    copied = set()
    for line in (REPO / "docker" / "Dockerfile").read_text().splitlines():
        if line.startswith("COPY "):
            copied.update(line.split()[1:-1])
    needed = {"pyproject.toml", "setup.py", "README.md", "LICENSE", "zencosim", *layer_folders()}
    assert needed <= copied, f"the image would miss {sorted(needed - copied)}"
    assert all((REPO / name).exists() for name in copied)
