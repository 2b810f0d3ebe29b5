"""Packaging: the repository's layer folders become sub-packages of the one import package ``zencosim``.

``zencosim/`` (the entry points: API and CLI) is the package itself; each top-level folder below is
installed as ``zencosim.<folder>``, with every sub-package found in it, so that a new sub-package
cannot be left out of a wheel. Metadata and dependencies: pyproject.toml.
"""
from setuptools import find_packages, setup

LAYER_FOLDERS = ("manager", "subsystems", "compensation", "recordings", "scenes")

packages = find_packages(include=["zencosim", "zencosim.*"])
for folder in LAYER_FOLDERS:
    packages += [f"zencosim.{name}" for name in find_packages(include=[folder, f"{folder}.*"])]

setup(packages=packages, package_dir={f"zencosim.{folder}": folder for folder in LAYER_FOLDERS})
