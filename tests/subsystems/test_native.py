"""``subsystems.native``: a shipped C file compiled once and kept, so that the next process loads it without
compiling; a damaged or unwritable cache is passed by. Each case runs in processes of its own, with a cache of its
own and a compiler that notes each of its runs."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from zencosim.subsystems.native import CACHE_DIR

LOAD = ("from zencosim.subsystems.native import library; "
        "print(library('zencosim.manager.scheme', 'register_loop.c') is not None)")


@pytest.fixture
def noted_compiler(tmp_path):
    """A C compiler that notes each run in a file, then is the system's: (its path, the file)."""
    runs = tmp_path / "compiler runs"
    compiler = tmp_path / "cc"
    compiler.write_text(f"#!/bin/sh\necho run >> '{runs}'\nexec cc \"$@\"\n")
    compiler.chmod(0o755)
    return compiler, runs


def _loaded(compiler, cache) -> bool:
    environment = {**os.environ, "CC": str(compiler), CACHE_DIR: str(cache)}
    result = subprocess.run([sys.executable, "-c", LOAD], env=environment, capture_output=True, text=True, check=True)
    return result.stdout.strip() == "True"


def _runs(runs) -> int:
    return len(runs.read_text().splitlines()) if runs.exists() else 0


def test_the_next_process_loads_the_kept_library_without_compiling(noted_compiler, tmp_path):
    compiler, runs = noted_compiler
    assert _loaded(compiler, tmp_path / "cache") and _runs(runs) == 1
    assert _loaded(compiler, tmp_path / "cache") and _runs(runs) == 1
    (kept,) = (tmp_path / "cache" / "native").iterdir()
    assert kept.name.startswith("register_loop-") and kept.suffix == ".so"


def test_a_damaged_library_in_the_cache_is_compiled_again_and_replaced(noted_compiler, tmp_path):
    compiler, runs = noted_compiler
    assert _loaded(compiler, tmp_path / "cache")
    (kept,) = (tmp_path / "cache" / "native").iterdir()
    kept.write_bytes(b"not a shared library")
    assert _loaded(compiler, tmp_path / "cache") and _runs(runs) == 2
    assert _loaded(compiler, tmp_path / "cache") and _runs(runs) == 2  # the replacement is whole


def test_a_cache_that_cannot_be_written_is_passed_by(noted_compiler, tmp_path):
    """The cache's place is a file: every process compiles, and loads what it compiled."""
    compiler, runs = noted_compiler
    (tmp_path / "a file").write_text("")
    assert _loaded(compiler, tmp_path / "a file") and _loaded(compiler, tmp_path / "a file") and _runs(runs) == 2
