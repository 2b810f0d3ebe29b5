"""What a recording holds: its channels, the names of their values, and the run's metadata.

One MCAP channel per key of the run (docs/protocol.md), with the key under ``zencosim/<run-id>/`` as
its topic: ``<sub>/commands`` (the commands the scheme computed for a subsystem: INIT and STEP carry
its input polynomial, ``rows × inputs``, row ``i`` multiplying ``tau**i``), ``<sub>/y`` (its
replies: OUTPUT carries its outputs) and ``manager/status`` (the manager's status after every
macro-step, manager.wire.status). A channel's metadata names its values and their units, so a recording
is read without the scene.

The ``zencosim`` metadata record describes the run (scene, digest, overrides, software versions,
bus, run id; the host and the scene's path only when asked); the attachment ``scene.toml`` is the scene after overrides, enough to re-run it;
the ``zencosim.end`` metadata record, written when the recorder finishes, holds the outcome and, per
channel, what the manager published, what the recorder received and what was lost, and what the file
holds before it: the messages recorded per channel, the number of chunks and the SHA-256 of those bytes.
"""
from __future__ import annotations

import functools
import json
import platform
import socket
import time
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np

from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scene.load import Scene
from zencosim.manager.wire.status import StatusReport

FORMAT = "zencosim-recording/2"  # a typed message per channel (recordings.schema); log time = wall clock
FORMAT_1 = "zencosim-recording/1"  # one generic message for every channel, log time = simulated time
RUN_METADATA = "zencosim"
END_METADATA = "zencosim.end"
SCENE_ATTACHMENT = "scene.toml"
CONTENT_DIGEST = "content_sha256"  # the end record's SHA-256 of every byte of the file before it
STATUS_TOPIC = "manager/status"
COMMANDS = "commands"  # the channel of a subsystem's commands; its replies are "y"


@dataclass(frozen=True)
class ChannelSpec:
    """One channel: ``topic`` is the key under the run; ``names`` and ``units`` describe its values."""

    topic: str
    source: str  # the subsystem, or "manager"
    role: str  # "inputs", "outputs" or "status"
    names: tuple[str, ...]
    units: tuple[str, ...]
    measured: tuple[str, ...] = ()  # status fields measured on the wall clock (differ between runs)

    def metadata(self) -> dict[str, str]:
        return {"source": self.source, "role": self.role, "names": json.dumps(self.names),
                "units": json.dumps(self.units), "measured": json.dumps(self.measured)}

    @classmethod
    def from_metadata(cls, topic: str, metadata: dict[str, str]) -> "ChannelSpec":
        """Raises KeyError or ValueError when the metadata is not a zencosim channel's."""
        return cls(topic, metadata["source"], metadata["role"], tuple(json.loads(metadata["names"])),
                   tuple(json.loads(metadata["units"])), tuple(json.loads(metadata["measured"])))


def channel_specs(plan: Plan, status: StatusReport) -> list[ChannelSpec]:
    """The channels of a run: ``<sub>/commands`` and ``<sub>/y`` per subsystem in scene order, then the status."""
    specs = []
    for sub in plan.subsystems:
        specs.append(ChannelSpec(f"{sub.name}/{COMMANDS}", sub.name, "inputs", tuple(p.name for p in sub.inputs),
                                 tuple(p.unit for p in sub.inputs)))
        specs.append(ChannelSpec(f"{sub.name}/y", sub.name, "outputs", tuple(p.name for p in sub.outputs),
                                 tuple(p.unit for p in sub.outputs)))
    specs.append(ChannelSpec(STATUS_TOPIC, "manager", "status", tuple(f.name for f in status.fields),
                             tuple(f.unit for f in status.fields), tuple(f.name for f in status.fields if f.measured)))
    return specs


def status_index(specs: list[ChannelSpec]) -> int:
    """The index of the run's status channel among ``specs`` (a recording's channels, or ``channel_specs``)."""
    return next(i for i, spec in enumerate(specs) if spec.role == "status")


@functools.cache
def _zencosim_version() -> str:
    """The installed zencosim's version, read once (``importlib.metadata`` parses the package's metadata at every
    call: about 1.4 ms of a recorded run's start)."""
    return version("zencosim")


def run_metadata(scene: Scene, plan: Plan, bus: str, run_id: str, realtime: bool,
                 host_info: bool = False) -> dict[str, str]:
    """The ``zencosim`` metadata record of a run; ``host_info`` adds the host's name and the scene file's
    absolute path (left out unless asked: a recording is shared)."""
    host = {"host": socket.gethostname(), "scene_source": str(scene.path)} if host_info else {}
    return {
        "format": FORMAT,
        "zencosim": _zencosim_version(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scene": scene.name,
        "scene_digest": scene.digest,
        "scene_file": Path(scene.path).name,
        "overrides": json.dumps(list(scene.overrides)),
        "bus": bus,
        "run_id": run_id,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "macro_step_ns": str(plan.base_step_ns),
        "steps": str(plan.n_ticks),
        "realtime": json.dumps(realtime),
        **host,
    }
