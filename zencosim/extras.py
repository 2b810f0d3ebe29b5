"""Optional parts of zencosim and what installs them.

The core install runs co-simulations, records and verifies them, and writes CSV and NPZ results. The
Rerun viewer, plots, Parquet files and FMUs need extras: ``pip install 'zencosim[rerun]'``, ``[plots]``,
``[parquet]``, ``[fmu]``, or ``[all]``. A command that needs a missing extra says which before it starts work.

A leaf module: any layer may import it.
"""
from __future__ import annotations

import importlib.util

EXTRAS = {  # extra -> the modules it provides
    "rerun": ("rerun",),
    "plots": ("matplotlib",),
    "parquet": ("pyarrow",),
    "fmu": ("fmpy",),
}


class MissingExtra(ImportError):
    """A feature whose optional dependencies are not installed; the message gives the pip command."""

    def __init__(self, extra: str, what: str) -> None:
        self.extra = extra
        super().__init__(f"{what} needs the optional dependencies of zencosim[{extra}]; install them with: "
                         f"pip install 'zencosim[{extra}]'")


def require(extra: str, what: str) -> None:
    """Raise :class:`MissingExtra` unless every module of ``extra`` can be imported; ``what`` names the feature."""
    if any(importlib.util.find_spec(module) is None for module in EXTRAS[extra]):
        raise MissingExtra(extra, what)
