"""A run's arrays in bounded memory: the newest rows in a window, the older ones spilled to a file.

A scheme fills its arrays (trajectories, residual power and energy, release times) row by row, in order,
and reads back only the newest few rows (extrapolation, correctors). A :class:`RowWindow` holds
``history + block`` rows in memory; when a row past the window is written, the oldest ``block`` rows go
to the run's spill file in one write and the newest ``history`` rows move to the front. A run short
enough to fit (``rows <= history + block``) is never spilled: its window is the whole array.

When the run ends, :meth:`RowWindow.finish` gives the whole array: the window itself, or the spill file as
an ``np.memmap`` (read lazily, page by page: mapping it costs no memory). Whoever reads a finished array
to its end reads it in blocks with :func:`row_blocks`, which reads a spilled array from its file
(``os.pread``) and so keeps none of it resident. Spill files are unnamed temporary files (under
``TMPDIR``): they are gone once the last array that maps one is, or the process ends, however it ends.
"""
from __future__ import annotations

import mmap
import os
import tempfile
from typing import BinaryIO, Iterator

import numpy as np

try:
    from numpy.lib.array_utils import byte_bounds
except ImportError:  # numpy < 2
    byte_bounds = np.byte_bounds

KEEP_STEPS = 100_000  # a run of at most this many base macro-steps keeps its arrays whole in memory
BLOCK_ROWS = 8_192  # rows written to a spill file at once, and read back at once


class Spill:
    """Where one run's arrays go as it runs: unnamed temporary files in ``TMPDIR``."""

    def new_file(self, label: str) -> BinaryIO:
        return tempfile.TemporaryFile(prefix=f"zencosim-{label}-")


def spill_for(n_ticks: int, keep: bool | None) -> Spill | None:
    """The spill of a run of ``n_ticks`` base macro-steps, or None when it keeps everything in memory:
    ``keep`` True (always keep), False (always spill), None (keep runs of at most ``KEEP_STEPS`` steps)."""
    if keep is None:
        keep = n_ticks <= KEEP_STEPS
    return None if keep else Spill()


class RowWindow:
    """Rows ``0 … rows - 1`` of a ``(rows, width)`` array (``(rows,)`` when ``width`` is None), written in order,
    of which the newest are held in ``array`` from row ``offset`` on (see the module text)."""

    def __init__(self, rows: int, width: int | None, dtype, fill, history: int, spill: Spill | None,
                 label: str) -> None:
        self.rows, self.dtype, self.fill = rows, np.dtype(dtype), fill
        self.row_shape = () if width is None else (width,)
        capacity = rows if spill is None or rows <= history + BLOCK_ROWS else history + BLOCK_ROWS
        self.history = min(history, capacity)
        self.array = np.full((capacity, *self.row_shape), fill, dtype=self.dtype)
        self.offset = 0  # the row of array[0]
        self.end = capacity  # the first row past the window
        self._file = spill.new_file(label) if capacity < rows else None

    def advance(self, row: int) -> None:
        """Make ``row`` (at or after the window's start, at most one block past its end) writable."""
        if row >= self.end:
            moved = self.array.shape[0] - self.history  # rows that go to the file
            self._file.write(self.array[:moved].tobytes())
            self.array[:self.history] = self.array[moved:]
            self.array[self.history:] = self.fill
            self.offset += moved
            self.end += moved

    def put(self, index: int, value) -> None:
        """Write row ``index`` (in the window, or at most one block past its end), advancing the window first
        when it lies past the end."""
        if index >= self.end:
            self.advance(index)
        self.array[index - self.offset] = value

    def put_rows(self, start: int, values: np.ndarray) -> None:
        """Write rows ``start …`` from ``values`` (the next rows to write, in order), advancing the window as
        they pass its end."""
        done = 0
        while done < len(values):
            index = start + done
            if index >= self.end:
                self.advance(index)
            count = min(len(values) - done, self.end - index)
            self.array[index - self.offset:index - self.offset + count] = values[done:done + count]
            done += count

    def row(self, index: int) -> np.ndarray:
        """Row ``index`` of the window (one of its newest ``history`` rows, or a later one)."""
        return self.array[index - self.offset]

    def finish(self, rows: int | None = None) -> np.ndarray:
        """The whole array, of its first ``rows`` rows (default: all): the window, or its spill file mapped."""
        rows = self.rows if rows is None else rows
        if self._file is None:
            return self.array[:rows]
        held = min(self.array.shape[0], max(rows - self.offset, 0))
        self._file.write(self.array[:held].tobytes())
        self.array[:] = self.fill
        for start in range(self.offset + held, rows, len(self.array)):  # rows never written (a run that stopped early)
            self._file.write(self.array[:min(len(self.array), rows - start)].tobytes())
        self._file.flush()
        spilled, self._file = self._file, None
        self.array = self.array[:0]
        if rows == 0:
            return np.empty((0, *self.row_shape), dtype=self.dtype)
        mapped = np.memmap(spilled, dtype=self.dtype, mode="r", shape=(rows, *self.row_shape))
        mapped.spill_file = spilled  # read_rows reads it; it closes when the array is gone
        return mapped


def row_blocks(array: np.ndarray, start: int = 0, stop: int | None = None,
               block: int = BLOCK_ROWS) -> Iterator[tuple[int, np.ndarray]]:
    """``(first row, rows)`` of ``array[start:stop]`` in blocks of ``block`` rows, each read as
    :func:`read_rows` reads it; an array held in memory in one block (a view: it costs nothing, and sums over
    it are numpy's, as they were before runs could spill)."""
    stop = len(array) if stop is None else stop
    if not spilled(array):
        if stop > start:
            yield start, array[start:stop]
        return
    for first in range(start, stop, block):
        yield first, read_rows(array, first, min(first + block, stop))


def read_rows(array: np.ndarray, start: int, stop: int) -> np.ndarray:
    """``array[start:stop]``; when ``array`` is a spilled array or a view of one (a column, every n-th row), the
    rows are read from its file (a copy), so that reading it to its end leaves none of it resident."""
    view = array[start:stop]
    mapped = _spilled_base(array)
    if mapped is None or view.size == 0 or any(stride < 0 for stride in view.strides):
        return view
    low, high = byte_bounds(view)
    base_low, _ = byte_bounds(mapped)
    data = os.pread(mapped.spill_file.fileno(), high - low, mapped.offset + low - base_low)
    return np.ndarray(view.shape, view.dtype, buffer=data, strides=view.strides).copy()


def spilled(array: np.ndarray) -> bool:
    """Whether ``array`` is a spilled array (``RowWindow.finish``) or a view of one: read it in blocks."""
    return _spilled_base(array) is not None


def _spilled_base(array: np.ndarray) -> np.memmap | None:
    """The spilled array (``RowWindow.finish``) that ``array`` is or views, or None."""
    while array is not None and isinstance(array, np.ndarray):
        if isinstance(array, np.memmap) and isinstance(array.base, mmap.mmap) and hasattr(array, "spill_file"):
            return array
        array = array.base
    return None
