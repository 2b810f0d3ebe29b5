"""Messages a process of a Zenoh run took off the network and dropped, counted per key.

A message on a run's key that no subsystem of the run publishes on (``zencosim/<run>/X/log``, X no
subsystem), a batch or reply that is malformed (its header, its length), and a reply that does not
answer the command the replica awaits (its CRC-32 reference, or its step: ``manager.scheme.replica``)
is dropped, never taken, and counted here with the key it came on, the first reason, and the
publisher when Zenoh gives one (a sample carries its publisher's id only when that publisher attached
it: ``Sample.source_info``). The manager counts what it takes from ``<sub>/log``; each subsystem
process what it takes from its sources' ``<sub>/y`` and its own ``<sub>/u``, and reports it with its
timing. The run summary lists them all (``dropped_messages``, docs/summary.md) and a run that stalls
names them.
"""
from __future__ import annotations

import threading

import zenoh


def publisher(sample: zenoh.Sample) -> str | None:
    """The Zenoh id of the publisher of ``sample``, when it attached its source info (None otherwise)."""
    info = sample.source_info
    if info is None:
        return None
    return f"zenoh id {info.source_id.zid} entity {info.source_id.eid}"


class DroppedMessages:
    """Per key: how many messages were dropped, why the first was, and its publisher if known (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_key: dict[str, dict] = {}

    def add(self, key: str, reason: str, source: str | None = None) -> None:
        with self._lock:
            entry = self._by_key.setdefault(key, {"count": 0, "reason": reason, "publisher": source})
            entry["count"] += 1

    def report(self) -> dict[str, dict]:
        """``{key: {"count", "reason" (of the first), "publisher" (None: unknown)}}``, JSON-ready."""
        with self._lock:
            return {key: dict(entry) for key, entry in self._by_key.items()}


def checked(report) -> dict[str, dict]:
    """The entries of a report another process sent (JSON from the network) that have the form of
    :meth:`DroppedMessages.report`; anything else is left out."""
    if not isinstance(report, dict):
        return {}
    return {str(key): {"count": entry["count"], "reason": str(entry.get("reason", "")),
                       "publisher": None if entry.get("publisher") is None else str(entry["publisher"])}
            for key, entry in report.items()
            if isinstance(entry, dict) and isinstance(entry.get("count"), int) and not isinstance(entry["count"], bool)}


def merge(reports: dict[str, dict[str, dict]]) -> dict[str, dict]:
    """One report from each process's (``{process: report}``): per key, the counts added, ``seen_by`` the
    processes that dropped messages there, the first reason and publisher found."""
    merged: dict[str, dict] = {}
    for process, report in reports.items():
        for key, entry in report.items():
            into = merged.setdefault(key, {"count": 0, "reason": entry["reason"], "publisher": entry.get("publisher"),
                                           "seen_by": []})
            into["count"] += entry["count"]
            into["seen_by"].append(process)
    return merged


def describe(merged: dict[str, dict]) -> str:
    """The drops of :func:`merge` in one sentence, for an error message ("" when there are none)."""
    return "; ".join(f"{entry['count']} dropped on {key} by {', '.join(entry['seen_by'])}"
                     + (f" from {entry['publisher']}" if entry.get("publisher") else "") + f" (first: {entry['reason']})"
                     for key, entry in merged.items())
