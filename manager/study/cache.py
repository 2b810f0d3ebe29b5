"""The study cache: one JSON file per measured point, so that an interrupted study resumes and a grid with one
more value runs only the new points.

A point's file is named by the digest of the scene it runs (``Scene.digest``: the scene after every
override, the derived ones included) and the number of repeats, in a folder named by the digest of the
study's scene (beside it, where the study extrapolates its reference, the point's output signals:
``signals_path``); a file is written whole (to a temporary name, then renamed) as soon as its point is done.
"""
from __future__ import annotations

import json
import os
from pathlib import Path


class StudyCache:
    """Measured points of one scene under ``root``."""

    def __init__(self, root: str | Path, scene_digest: str, repeats: int) -> None:
        self.folder = Path(root) / scene_digest[:16]
        self.repeats = repeats

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}-r{self.repeats}.json"

    def signals_path(self, key: str) -> Path:
        """Where point ``key``'s output signals are kept (``measure.save_signals``: the same for any repeats)."""
        return self.folder / f"{key}-signals.npz"

    def read(self, key: str) -> dict | None:
        """The cached entry of point ``key`` (None: not measured yet, or a file that does not read)."""
        try:
            return json.loads(self._path(key).read_text())
        except (OSError, ValueError):
            return None

    def write(self, key: str, entry: dict) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self._path(key)
        temporary = path.with_suffix(f".{os.getpid()}.tmp")
        temporary.write_text(json.dumps(entry, indent=1) + "\n")
        temporary.replace(path)
