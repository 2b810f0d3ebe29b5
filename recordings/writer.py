"""Write one run to an MCAP file: header, schemas, channels, metadata, scene, then every wire message.

Messages go into ZSTD-compressed chunks of about ``CHUNK_BYTES`` (``recordings.mcap_file``); a chunk
is also closed and handed to the operating system once it is ``FLUSH_INTERVAL_S`` old (at the next
message, or when the recorder is idle: ``flush_if_due``). A recorder killed outright (SIGKILL)
therefore leaves a file whose every complete chunk is readable: it loses at most the messages of the
last ``FLUSH_INTERVAL_S`` (one chunk at most). ``finish`` writes the ``zencosim.end`` record, the
MCAP summary and the footer. The end record comes after the last chunk and holds what the file holds
before it — the messages recorded per channel, the number of chunks, and the SHA-256 of every byte
before it (header, schemas, channels, the run's metadata, the scene, every chunk and its message
indexes): ``recordings.reader`` compares them with what it reads, so no damage before the end record
goes unnoticed, the metadata and the embedded scene included.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from zencosim.recordings import RecordingError
from zencosim.recordings.encoding import BatchEncoder
from zencosim.recordings.layout import (
    CONTENT_DIGEST,
    END_METADATA,
    RUN_METADATA,
    SCENE_ATTACHMENT,
    ChannelSpec,
    status_index,
)
from zencosim.recordings.mcap_file import McapFile
from zencosim.recordings.schema import MESSAGE_ENCODING, SCHEMA_ENCODING, ChannelSchema

CHUNK_BYTES = 256 * 1024  # uncompressed bytes of messages per chunk
FLUSH_INTERVAL_S = 0.5  # a chunk older than this is written out at the next message


class RecordingWriter:
    """An MCAP file being written; ``write`` takes batches of wire messages (manager.wire.protocol)."""

    def __init__(self, path: str | Path, metadata: dict[str, str], scene_toml: str,
                 channels: list[ChannelSpec]) -> None:
        self.path = Path(path)
        self.channels = channels
        try:
            self._file = open(self.path, "wb")
        except OSError as error:
            raise RecordingError(f"cannot write recording {self.path}: {error.strerror}") from None
        self._mcap = McapFile(self._file, f"zencosim {metadata['zencosim']}", CHUNK_BYTES)
        schemas = [ChannelSchema(c) for c in channels]
        ids = [self._mcap.channel(c.topic, MESSAGE_ENCODING, self._mcap.schema(schema.name, SCHEMA_ENCODING,
                                                                                schema.descriptor_set), c.metadata())
               for c, schema in zip(channels, schemas)]
        self._ids = np.array(ids)
        self._encoder = BatchEncoder(schemas, ids, status_index(channels))
        self._stamp = time.time_ns()  # stamps the messages before the first status
        self._mcap.metadata(RUN_METADATA, metadata)
        self._mcap.attachment(SCENE_ATTACHMENT, "application/toml", scene_toml.encode(), time.time_ns())
        self._mcap.flush()
        self.received = [0] * len(channels)
        self.malformed: list[str] = []  # why each rejected message was rejected
        self._last_flush = time.monotonic()

    def write(self, channels: np.ndarray, sizes: np.ndarray, stamps: np.ndarray, messages: bytes) -> None:
        """Record a batch: ``messages`` one after the other (``sizes``), of channel indices ``channels``; each
        status message takes the next wall-clock stamp [ns] of ``stamps``, which is the log time of it and
        the messages after it. A malformed message is counted and described, not recorded."""
        for index, count in enumerate(np.bincount(channels, minlength=len(self.channels)).tolist()):
            self.received[index] += count
        batch = self._encoder.encode(channels, sizes, stamps, messages, self._stamp,
                                     lambda i: self.channels[int(channels[i])].topic)
        self._stamp = batch.carry
        self.malformed += batch.malformed
        self._mcap.messages(batch.records, self._ids[batch.channels], batch.log_times, batch.offsets)
        self.flush_if_due()

    def flush_if_due(self) -> None:
        """Write the open chunk out when it is older than ``FLUSH_INTERVAL_S``."""
        now = time.monotonic()
        if now - self._last_flush > FLUSH_INTERVAL_S:
            self._mcap.flush()
            self._last_flush = now

    def finish(self, outcome: str, published: dict[str, int] | None) -> dict:
        """Close the file with its end record; return what it says (see ``end_record``)."""
        end = self.end_record(outcome, published)
        self._mcap.flush()  # the last chunk goes before the end record, so that the record covers every message
        digest, counts, chunks = self._mcap.written()
        stored = {**end, "path": self.path.name,  # the file's own name: no absolute path in the file
                  "recorded": {spec.topic: counts.get(int(i), 0) for spec, i in zip(self.channels, self._ids)},
                  "chunks": chunks, CONTENT_DIGEST: digest}
        self._mcap.metadata(END_METADATA, {key: value if isinstance(value, str) else json.dumps(value)
                                           for key, value in stored.items()})
        self._mcap.finish()
        self._file.close()
        return end

    def end_record(self, outcome: str, published: dict[str, int] | None) -> dict:
        """Outcome, and per channel what was published (None when unknown), received and lost."""
        channels = {}
        for spec, received in zip(self.channels, self.received):
            sent = None if published is None else published.get(spec.topic, 0)
            channels[spec.topic] = {"published": sent, "received": received,
                                    "lost": None if sent is None else max(sent - received, 0)}
        known = [c["lost"] for c in channels.values() if c["lost"] is not None]
        return {"outcome": outcome, "path": str(self.path), "messages": sum(self.received) - len(self.malformed),
                "lost": sum(known) if published is not None else None, "channels": channels,
                "malformed": len(self.malformed), "first_malformed": self.malformed[0] if self.malformed else "",
                "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
