"""The versions two hosts of a run should share: zencosim's, its wire protocol's, and those a run depends on.

A leaf module of the standard library only, so that ``zencosim --version`` answers from the package metadata
without importing the runtime. Any layer may import it (``manager.wire.protocol`` takes its version from here).
"""
from __future__ import annotations

import platform
from importlib.metadata import version

WIRE_PROTOCOL = 2  # the version byte of every message's header (manager.wire.protocol)


def versions() -> str:
    """zencosim's version and those a run depends on (two hosts of a run should show the same)."""
    return (f"zencosim {version('zencosim')} (wire protocol {WIRE_PROTOCOL}; zenoh {version('eclipse-zenoh')}, "
            f"numpy {version('numpy')}, python {platform.python_version()})")
