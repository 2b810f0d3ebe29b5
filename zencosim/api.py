"""The Python API of zencosim: load a scene, run it on either bus, take its results away (docs/api.md).

    import zencosim

    scene = zencosim.load_scene("two_mass_damped", {"manager.macro_step": 0.002})
    result = zencosim.run(scene)                 # bus="zenoh": every subsystem in its own process
    x2 = result.signal("x2")                     # x2.time [s], x2.values, x2.unit == "m"
    result.summary["signals"]["x2"]["nrms"]      # the summary of `zencosim run --summary` (docs/summary.md)
    result.write("results.csv")                  # every signal, one table per communication grid

Everything here is also what the command line uses; the modules under ``zencosim.manager``,
``zencosim.subsystems``, ``zencosim.compensation`` and ``zencosim.recordings`` are the implementation.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

from zencosim.extras import MissingExtra as MissingExtra
from zencosim.manager.bus.security import SecurityError as SecurityError
from zencosim.manager.bus.security import ZenohSecurity
from zencosim.manager.bus.zenoh_session import ZenohOptions
from zencosim.manager.results.output_files import OutputFileError as OutputFileError
from zencosim.manager.results.tables import Signal, Table, record_signals, record_tables, tables, write_tables
from zencosim.manager.run import BUSES, execute, summarize_run
from zencosim.manager.scene.load import Scene, bundled_scene_names
from zencosim.manager.scene.load import SceneError as SceneError
from zencosim.manager.scene.load import load_scene as _load_scene
from zencosim.manager.scene.overrides import toml_value
from zencosim.manager.scheme.base import RunRecord
from zencosim.manager.scheme.base import SubsystemFailure as SubsystemFailure
from zencosim.manager.wire.protocol import ProtocolError as ProtocolError
from zencosim.recordings import RecordingError as RecordingError
from zencosim.recordings.export import recorded_signals
from zencosim.recordings.reader import read_recording

# the public names are listed once, in zencosim/__init__.py; the errors are imported here for it

def bundled_scenes() -> list[str]:
    """Names of the scenes that ship with zencosim (the papers' benchmarks)."""
    return bundled_scene_names()


def load_scene(scene: str | Path, overrides: Mapping[str, object] | Sequence[str] = ()) -> Scene:
    """A bundled scene by name, or a TOML scene file, with ``overrides`` applied and everything validated.

    ``overrides`` maps dotted keys to values (``{"manager.macro_step": 0.002}``) or is a list of
    ``"key=value"`` strings as ``--set`` takes them. Raises :class:`SceneError` listing every problem.
    """
    if isinstance(overrides, Mapping):
        overrides = [f"{key}={toml_value(value)}" for key, value in overrides.items()]
    return _load_scene(str(scene), list(overrides))


@dataclass(frozen=True)
class _Signals:
    """Named signals with their time vectors and units, as tables and files."""

    signals: Mapping[str, Signal]  # by name: every output of every subsystem, then each bond's residuals

    def signal(self, name: str) -> Signal:
        """The signal ``name`` (``"x2"``, ``"S1.energy"``, ``"delta_p.c1"``)."""
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(f"no signal {name!r}; expected one of {', '.join(self.signals)}") from None

    def tables(self) -> list[Table]:
        """One table per communication grid, finest first (``manager.results.tables``)."""
        return tables(self.signals)

    def write(self, path: str | Path) -> list[Path]:
        """Write every signal to ``path`` (.csv, .npz, .parquet); one file per grid of a multi-rate run.
        Returns the files written."""
        return write_tables(self.tables(), path)


@dataclass(frozen=True)
class Result(_Signals):
    """One run of a scene: its signals, its summary and the raw record."""

    scene: Scene
    bus: str
    summary: dict  # as ``zencosim run --summary`` writes it (docs/summary.md)
    record: RunRecord  # the run as the scheme recorded it, on the base macro-step grid

    def write(self, path: str | Path) -> list[Path]:
        """Write every signal to ``path`` (.csv, .npz, .parquet); one file per grid of a multi-rate run, block
        by block (a long run's arrays are read from their files). Returns the files written."""
        return write_tables(record_tables(self.record), path)

    @property
    def digest(self) -> str:
        """sha256 of every output trajectory: equal digests mean bit-identical runs."""
        return self.summary["digest"]


@dataclass(frozen=True)
class Recording(_Signals):
    """The signals of a recorded run (``zencosim run --record``), read back from its MCAP file."""

    path: Path
    scene_name: str
    outcome: str  # "completed", "interrupted", "failed: …", or unknown when the recorder did not finish


def run(scene: Scene | str | Path, bus: str = "inproc", *, record: str | Path | None = None,
        realtime: bool | None = None, progress: Callable[[int], None] | None = None,
        keep: bool | None = None) -> Result:
    """Run ``scene`` (a loaded :class:`Scene`, or a bundled name or file loaded as it is) on ``bus``.

    ``record``: write every message of the run to this MCAP file. ``realtime``: pace macro-steps to
    the wall clock (default: the scene's ``manager.realtime``). ``progress(step)`` is called every few
    hundred macro-steps. Over Zenoh, the scene's ``manager.zenoh_config`` configures every session
    (:class:`SecurityError` when that file cannot be used). ``keep``: hold the run's arrays in memory (True),
    or spill them to temporary files as the run goes, so that memory does not grow with the run's length
    (False); by default runs of up to ``KEEP_STEPS`` (100 000) macro-steps are held, longer ones spilled. A
    spilled run's signals read their files as they are used. Raises :class:`SceneError` for a scene that
    cannot run, :class:`SubsystemFailure` or :class:`ProtocolError` for a run that failed, and
    ``zencosim.recordings.RecorderLost`` when the recorder process of a recorded run is gone.
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if bus not in BUSES:
        raise ValueError(f"unknown bus {bus!r}; expected one of {', '.join(BUSES)}")
    recorder = None
    if record is not None:
        from zencosim.recordings.recorder import Recorder
        recorder = Recorder(record)
    options = {}
    if bus == "zenoh":  # the scene's manager.zenoh_config, if any (docs/security.md)
        security = ZenohSecurity().checked_with_scene(scene.manager.zenoh_config, scene.path)
        options = {"zenoh_options": ZenohOptions(security=security)}
    record_, wall_s = execute(scene, bus, realtime, progress, recorder=recorder, keep=keep, **options)
    summary = summarize_run(scene, record_, bus, wall_s, recorder, keep)
    return Result(record_signals(record_), scene, bus, summary, record_)


def load_recording(path: str | Path) -> Recording:
    """The signals of the recording at ``path``; :class:`RecordingError` naming the file when it is not one."""
    recording = read_recording(path)
    outcome = recording.end["outcome"] if recording.end else "unknown: the recorder did not finish"
    return Recording(recorded_signals(recording), recording.path, recording.info["scene"], outcome)

