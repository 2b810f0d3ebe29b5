"""The Rerun replay of a recorded two_mass_damped run, read back from the .rrd with the SDK's chunk reader:
one panel per quantity and unit, series named with their units, the sim_time timeline, the mechanism
drawn where the recorded outputs say, and a clear refusal when no viewer can be spawned.

The replay runs as its own process (``zencosim replay``), as a user runs it.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

import zencosim
from tests.conftest import REPO
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.mechanism import SPAN_LANES, lane_scale
from zencosim.recordings.reader import read_recording
from zencosim.subsystems.sketch import BOX, LANE

pytestmark = pytest.mark.multiprocess

RERUN = Path(sys.executable).with_name("rerun")  # the Rerun command line the rerun-sdk installs beside Python

UNITS_OF_PANELS = {"positions": "m", "velocities": "m/s", "forces": "N", "energies": "J", "residual_power": "W",
                   "residual_energy": "J", "step_timing": "µs", "wall_time": "s"}


def _zencosim(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "zencosim", *args], capture_output=True, text=True, cwd=REPO,
                          timeout=180, env=env)


def _columns(store_chunks) -> dict[str, pa.Table]:
    """Entity path → its rows (every chunk of it, columns unified)."""
    batches = defaultdict(list)
    for chunk in store_chunks:
        batches[chunk.entity_path].append(chunk.to_record_batch())
    return {entity: pa.concat_tables([pa.Table.from_batches([b]) for b in found], promote_options="default")
            for entity, found in batches.items()}


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """(recording, its data by entity, its blueprint by entity) of a 2 s run replayed into a .rrd file."""
    from rerun.chunk import RrdReader
    folder = tmp_path_factory.mktemp("replayed")
    mcap, rrd = folder / "run.mcap", folder / "run.rrd"
    zencosim.run(zencosim.load_scene("two_mass_damped", ["manager.duration=2.0"]), record=mcap)
    result = _zencosim("replay", str(mcap), "--rrd", str(rrd))
    assert result.returncode == 0, result.stderr
    reader = RrdReader(rrd)
    (blueprint,) = reader.blueprints()
    return read_recording(mcap), _columns(reader.stream()), _columns(reader.stream(store=blueprint))


def _values(table: pa.Table, column: str) -> list:
    return [v for v in table[column].to_pylist() if v is not None]


def _scalars(table: pa.Table) -> tuple[list[int], list[int], np.ndarray]:
    rows = table.filter(pc.is_valid(table["step"])).sort_by("step")
    return (rows["step"].to_pylist(), rows["sim_time"].cast(pa.int64()).to_pylist(),
            rows["Scalars:scalars"].combine_chunks().flatten().to_numpy(zero_copy_only=False))


def test_every_signal_is_a_series_under_its_quantity_named_with_its_unit(replayed):
    recording, data, _ = replayed
    expected = {"/positions/S2/x2": ("S2 x2 [m]", "m"), "/velocities/S2/v2": ("S2 v2 [m/s]", "m/s"),
                "/energies/S2/energy": ("S2 energy [J]", "J"), "/forces/S1/fc": ("S1 fc [N]", "N"),
                "/energies/S1/energy": ("S1 energy [J]", "J"),
                "/positions/S1/x2\\*": ("S1 x2* (received) [m]", "m"), "/forces/S2/fc\\*": ("S2 fc* (received) [N]", "N"),
                "/residual_power/c": ("residual power δP c [W]", "W"),
                "/residual_energy/c": ("residual energy δE c [J]", "J"),
                "/step_timing/step_wall_time": ("step wall time [µs]", "µs"), "/wall_time": ("wall time [s]", "s")}
    for entity, (name, unit) in expected.items():
        assert _values(data[entity], "SeriesLines:names") == [[name]], entity
        assert _values(data[entity], "unit") == [[unit]], entity
    # the values on the sim_time timeline are the recorded ones, bit for bit (timing: converted to µs)
    steps, times, outputs = recording.channels["S2/y"].table(Kind.OUTPUT)
    logged_steps, logged_times, x2 = _scalars(data["/positions/S2/x2"])
    assert logged_steps == steps.tolist() and logged_times == times.tolist()
    assert x2.tobytes() == outputs[:, 0].tobytes()
    status = recording.channels["manager/status"]
    _, _, values = status.table(Kind.STATUS)
    step_wall_time = values[:, status.spec.names.index("step_wall_time")]
    assert _scalars(data["/step_timing/step_wall_time"])[2].tobytes() == (step_wall_time * 1e6).tobytes()


def test_the_blueprint_has_one_panel_per_quantity_and_unit_over_the_whole_run(replayed):
    _, data, blueprint = replayed
    units = {entity: _values(table, "unit")[0][0] for entity, table in data.items() if "unit" in table.column_names}
    views = {entity: table for entity, table in blueprint.items()
             if entity.startswith("/view/") and entity.count("/") == 2}
    panels = {}
    for entity, table in views.items():
        (kind,) = _values(table, "ViewBlueprint:class_identifier")[0]
        if kind != "TimeSeries":
            continue
        (origin,) = _values(table, "ViewBlueprint:space_origin")[0]
        assert _values(blueprint[f"{entity}/ViewContents"], "ViewContents:query") == [["$origin/**"]]
        inside = {units[e] for e in units if e.startswith(origin + "/") or e == origin}
        (title,) = _values(table, "ViewBlueprint:display_name")[0]
        panels[origin.strip("/")] = (inside, title)
        ranges = _values(blueprint[f"{entity}/VisibleTimeRanges"], "VisibleTimeRanges:ranges")[0]
        assert [r["timeline"] for r in ranges] == ["sim_time"]
        assert [r["range"] for r in ranges] == [{"start": None, "end": None}]  # unbounded: the whole run
    assert set(panels) == set(UNITS_OF_PANELS)
    for root, (inside, title) in panels.items():
        assert inside == {UNITS_OF_PANELS[root]}, (root, inside)  # never two units in one panel
        assert title.endswith(f"[{UNITS_OF_PANELS[root]}]"), title
    assert _values(blueprint["/time_panel"], "TimePanelBlueprint:timeline") == [["sim_time"]]


def test_the_mechanism_moves_as_the_recorded_outputs_say(replayed):
    recording, data, _ = replayed
    _, times, outputs = recording.channels["S2/y"].table(Kind.OUTPUT)
    bodies = data["/mechanism/S2/bodies"].filter(pc.is_valid(data["/mechanism/S2/bodies"]["sim_time"]))
    bodies = bodies.sort_by("sim_time")
    assert bodies["sim_time"].cast(pa.int64()).to_pylist() == times.tolist()
    centers = np.array([row[0] for row in bodies["Boxes2D:centers"].to_pylist()])
    half_sizes = np.array([row[0] for row in bodies["Boxes2D:half_sizes"].to_pylist()])
    # m2's box is where the re-executed S2 says, which is what S2 reported (x2), to the bit of Rerun's float32
    # positions; S2 is the second lane, one lane below the first (y = -LANE × the lane scale, drawn as + because
    # Rerun's y points down), its box the sketch's times the same scale: 1, 2, 5, … and never shrinking
    assert centers[:, 0].astype(np.float32).tobytes() == outputs[:, 0].astype(np.float32).tobytes()
    scales = centers[:, 1] / LANE
    assert set(scales.tolist()) <= {1.0, 2.0, 5.0, 10.0} and np.all(np.diff(scales) >= 0)
    assert np.allclose(half_sizes, BOX * scales[:, None], rtol=1e-6)  # float32
    # the lanes are at least a quarter (1 / SPAN_LANES) of the x span covered so far apart: m2's own span is a part
    x2_span = np.maximum.accumulate(outputs[:, 0]) - np.minimum.accumulate(outputs[:, 0])
    assert np.all(scales * LANE >= x2_span / SPAN_LANES) and scales[-1] > 1.0
    # S1's fc is the coupling force on m2, which m2 receives unchanged: the arrow points along it
    _, _, s1 = recording.channels["S1/y"].table(Kind.OUTPUT)
    arrows = data["/mechanism/forces/c"].filter(pc.is_valid(data["/mechanism/forces/c"]["sim_time"]))
    vectors = np.array([row[0] for row in arrows.sort_by("sim_time")["Arrows2D:vectors"].to_pylist()])
    assert np.all(np.sign(vectors[:, 0]) == np.sign(s1[:, 0])) and np.all(vectors[:, 1] == 0.0)
    assert _values(data["/events"], "TextLog:text") == [["run completed"]]


@pytest.mark.parametrize(("span", "scale"), [(0.0, 1.0), (4.0, 1.0), (4.001, 2.0), (18.0, 5.0), (20.0, 5.0),
                                             (20.5, 10.0), (2e3, 500.0), (math.nan, 1.0), (math.inf, 1.0)])
def test_the_lane_scale_is_the_least_of_1_2_5_10_that_spaces_the_lanes_a_quarter_of_the_span(span, scale):
    assert lane_scale(span) == scale


def test_the_replay_passes_the_rerun_tools_own_check(replayed):
    """``rerun rrd verify`` decodes every chunk against Rerun's schemas (of a 2 s replay: it takes about 50 s
    for the 10 s one of test_recorded_runs, whose content is checked series by series instead)."""
    recording, _, _ = replayed
    checked = subprocess.run([str(RERUN), "rrd", "verify", str(recording.path.with_suffix(".rrd"))],
                             capture_output=True, text=True, timeout=120)
    assert checked.returncode == 0, checked.stderr


def test_replay_spawn_without_a_viewer_says_why_and_exits_2(replayed, tmp_path):
    recording, _, _ = replayed
    env = {key: value for key, value in os.environ.items() if key not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = _zencosim("replay", str(recording.path), "--spawn", env=env)
    assert result.returncode == 2, result.stderr
    assert "no display for a Rerun viewer" in result.stderr and "--rrd FILE" in result.stderr
    assert "Traceback" not in result.stderr


def test_an_energy_controlled_run_shows_the_length_of_each_macro_step(tmp_path):
    """``/macro_step`` [ms]: each status's time minus the one before, at that status's step and time."""
    from rerun.chunk import RrdReader
    mcap, rrd = tmp_path / "energy.mcap", tmp_path / "energy.rrd"
    fine = {f"subsystems.{name}.micro_step": 1e-4 for name in ("S1", "S2")}
    scene = zencosim.load_scene("two_mass_damped", {**fine, "manager.macro_step": 1e-4, "manager.duration": 0.5,
                                                    "manager.step_control": "energy",
                                                    "manager.energy_control.max_step_size": 0.01,
                                                    "manager.energy_control.abs_tolerance": 1.0})
    ticks = np.asarray(zencosim.run(scene, record=mcap).record.point_ticks)
    result = _zencosim("replay", str(mcap), "--rrd", str(rrd))
    assert result.returncode == 0, result.stderr
    data = _columns(RrdReader(rrd).stream())
    assert _values(data["/macro_step"], "SeriesLines:names") == [["macro-step [ms]"]]
    steps, times, lengths = _scalars(data["/macro_step"])
    assert steps == ticks[1:].tolist() and times == (ticks[1:] * 100_000).tolist()
    assert np.array_equal(lengths, np.diff(ticks * 100_000) * 1e-6) and len(set(lengths.tolist())) > 3


def test_each_dimensionless_signal_has_a_panel_of_its_own_and_units_still_share_one():
    """Signals without a unit (``1``: an FMU's variables with none) each get a panel, so that a ±1 force does not
    flatten a ±0.17 position; signals with a unit keep one panel per quantity. The blueprint is built from these."""
    import rerun as rr

    from zencosim.recordings.layout import ChannelSpec
    from zencosim.recordings.rerun_view import RunView, blueprint
    specs = [ChannelSpec("A/y", "A", "outputs", ("force", "position", "x"), ("1", "1", "m")),
             ChannelSpec("B/y", "B", "outputs", ("position", "x"), ("1", "m")),
             ChannelSpec("B/commands", "B", "inputs", ("force",), ("1",))]
    view = RunView(rr.RecordingStream("zencosim-test"), specs, None)
    series = [s for group in view.series.values() for s in group]
    by_panel = {origin: [s for s in series if s.origin == origin] for origin in view.panels()}
    dimensionless = {s.entity for s in series if s.unit == "1"}
    assert len(dimensionless) == 4
    for origin, inside in by_panel.items():
        assert len({s.unit for s in inside}) == 1, origin  # never two units in one panel
        if inside[0].unit == "1":
            assert [s.entity for s in inside] == [origin], origin  # the signal alone, its panel titled with its name
            assert view.panels()[origin] == inside[0].label
    assert [len(inside) for origin, inside in by_panel.items() if inside[0].unit == "m"] == [2]
    assert len(by_panel) == 5
    blueprint(view)  # builds with a panel per origin
