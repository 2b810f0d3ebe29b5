"""The reply batches the manager's replica has not taken yet, in bounded memory.

Over Zenoh the manager's replica follows the run at idle priority (``manager.bus.zenoh_bus``): on a busy
machine it lags, and the subsystems' batches of replies wait for it. Up to ``MEMORY_BYTES`` of them wait in
memory; beyond that, newer batches go to an unnamed temporary file (``TMPDIR``) and are read back in order,
so a lag of any length costs disk, not memory.
"""
from __future__ import annotations

import os
import queue
import struct
import tempfile
import threading

MEMORY_BYTES = 1024 * 1024  # batches held in memory before newer ones go to the file
_RECORD = struct.Struct("<HI")  # length of the subsystem's name, of the batch
_IN_FILE = object()  # the token of a batch in the file


class Backlog:
    """A FIFO of ``(subsystem, batch)``, one producer thread and one consumer thread; ``None`` ends it."""

    def __init__(self, memory_bytes: int = MEMORY_BYTES) -> None:
        self.memory_bytes = memory_bytes
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._held = 0  # bytes of the batches in memory
        self._lock = threading.Lock()
        self._file = None
        self._written = self._read = 0  # file offsets

    def put(self, item: tuple[str, bytes] | None) -> None:
        if item is not None:
            name, batch = item
            with self._lock:
                if self._held + len(batch) > self.memory_bytes:
                    if self._file is None:
                        self._file = tempfile.TemporaryFile(prefix="zencosim-backlog-")
                    encoded = name.encode()
                    record = _RECORD.pack(len(encoded), len(batch)) + encoded + batch
                    os.pwrite(self._file.fileno(), record, self._written)
                    self._written += len(record)
                    item = _IN_FILE
                else:
                    self._held += len(batch)
        self._queue.put(item)

    def get(self) -> tuple[str, bytes] | None:
        item = self._queue.get()
        if item is None:
            return None
        with self._lock:
            if item is not _IN_FILE:
                self._held -= len(item[1])
                return item
            descriptor = self._file.fileno()
            name_length, batch_length = _RECORD.unpack(os.pread(descriptor, _RECORD.size, self._read))
            body = os.pread(descriptor, name_length + batch_length, self._read + _RECORD.size)
            self._read += _RECORD.size + name_length + batch_length
        return body[:name_length].decode(), body[name_length:]

    def get_waiting(self) -> list[tuple[str, bytes] | None]:
        """The next item (waiting for it) and every item that waits after it, up to and including the end (None)."""
        items = [self.get()]
        while items[-1] is not None and not self._queue.empty():
            items.append(self.get())
        return items

    def empty(self) -> bool:
        return self._queue.empty()
