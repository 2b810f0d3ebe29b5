"""What a run looks like in Rerun: its signals by physical quantity, its mechanism, its events.

Shared by the replay of a recording (``recordings.rerun_replay``) and the live view of a run
(``recordings.rerun_live``): both feed :class:`RunView` the messages of each channel in order, so a
live run and the replay of its recording log the same values.

Entities, one per series, grouped by quantity so that a panel never holds two units:
``/<quantity>/<subsystem>/<signal>`` for every output (and every received input: the value of its
polynomial at the start of each step), e.g. ``/positions/S2/x2``, ``/forces/S2/fc*``; a dimensionless
signal (unit ``1``: no unit tells what it is) has ``/signals_1/<subsystem>/<signal>`` and a panel of its own,
so that a ±1 force does not flatten a ±0.17 position beside it;
``/residual_power/<bond>`` and ``/residual_energy/<bond>`` (and any other per-bond status field,
``/<field>/<bond>``); ``/step_timing/<field>`` [µs] and ``/wall_time`` [s]; with an energy-controlled step,
``/macro_step`` [ms], the length of each macro-step (docs/step-control.md). Each series is named
with its unit (``S2 x2 [m]``), has a colour per subsystem (lighter for what it receives) and a
static ``unit``; a value that is NaN (a multi-rate bond where it is not evaluated) is left out, so the
line has no gaps. The mechanism is under ``/mechanism`` (``recordings.mechanism``), the flagged
residual-power spikes and how the run ended under ``/events``. Timelines: ``sim_time`` (simulated
time, the default) and ``step``.
"""
from __future__ import annotations

import heapq
import re
from dataclasses import dataclass

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from zencosim.manager.results.monitor import spike_intervals
from zencosim.manager.scene.load import Scene
from zencosim.manager.wire.protocol import Kind
from zencosim.recordings.layout import ChannelSpec
from zencosim.recordings.mechanism import Frame, Mechanism

APPLICATION = "zencosim"
QUANTITIES = {  # unit → entity root, panel title: one panel per quantity and unit
    "m": ("positions", "positions"), "m/s": ("velocities", "velocities"), "m/s^2": ("accelerations", "accelerations"),
    "N": ("forces", "forces"), "J": ("energies", "energies"), "1/kg": ("inverse_masses", "inverse masses"),
}
DIMENSIONLESS = "1"  # the unit of a signal without one (subsystems.units): a panel per signal
STATUS_QUANTITIES = {"delta_p": ("residual_power", "residual power δP"), "delta_e": ("residual_energy",
                                                                                      "residual energy δE")}
STEP_TIMING = ("step_timing", "step timing")  # the measured per-step durations, shown in µs
MACRO_STEP = ("macro_step", "macro-step")  # an energy-controlled run's: each status's time minus the one before, in ms
WALL_TIME = ("wall_time", "wall time")
PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
           (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))
PLOTTED = {"outputs": Kind.OUTPUT, "inputs": Kind.STEP, "status": Kind.STATUS}  # the messages a channel plots
EVENTS = "/events"
MECHANISM = "/mechanism"
WIDE = 3.0  # a mechanism this many times wider than high is drawn in a strip across the top
TIMING_RANGE = 3.0  # the step-timing panel opens on 0 … this × the 99th percentile


def _path(*parts: str) -> str:
    return "/" + "/".join(rr.escape_entity_path_part(part) for part in parts)


def _lighter(color: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(int(c + 0.5 * (255 - c)) for c in color)


@dataclass(frozen=True)
class Series:
    """One plotted signal: its entity, panel (origin, title with unit), name, unit, colour and where its values are."""

    entity: str
    origin: str  # the entity path of its panel: its quantity's root, or the series itself (a dimensionless one)
    panel: str  # the panel's title, with the unit
    label: str  # the series' name, with the unit
    unit: str
    color: tuple[int, ...]
    column: int  # index of the value in the message (inputs: in the polynomial's first row)
    scale: float = 1.0  # shown value = scale × recorded value (s → µs)


def series_of(spec: ChannelSpec, color: tuple[int, ...]) -> list[Series]:
    """The series a channel gives (see the module text)."""
    found = []
    for j, (name, unit) in enumerate(zip(spec.names, spec.units)):
        if spec.role == "status":
            prefix, dot, bond = name.partition(".")
            if dot:
                root, title = STATUS_QUANTITIES.get(prefix, (re.sub(r"\W", "_", prefix), prefix))
                found.append(Series(_path(root, bond), _path(root), f"{title} [{unit}]", f"{title} {bond} [{unit}]",
                                    unit, PALETTE[(j + 3) % len(PALETTE)], j))
            elif name in spec.measured and unit == "s" and name != "wall_time":
                found.append(Series(_path(STEP_TIMING[0], name), _path(STEP_TIMING[0]), f"{STEP_TIMING[1]} [µs]",
                                    f"{name.replace('_', ' ')} [µs]", "µs", PALETTE[(j + 5) % len(PALETTE)], j, 1e6))
            else:
                root, title = WALL_TIME if name == "wall_time" else (re.sub(r"\W", "_", name), name.replace("_", " "))
                label = f"{title} [{unit}]"
                found.append(Series(_path(root), _path(root), label, label, unit, PALETTE[7], j))
            continue
        root, title = QUANTITIES.get(unit, ("signals_" + re.sub(r"\W", "_", unit), "signals"))
        received = spec.role == "inputs"
        label = f"{spec.source} {name}{' (received)' if received else ''} [{unit}]"
        entity = _path(root, spec.source, name)
        origin, panel = (entity, label) if unit == DIMENSIONLESS else (_path(root), f"{title} [{unit}]")
        found.append(Series(entity, origin, panel, label, unit, _lighter(color) if received else color, j))
    return found


class RunView:
    """Logs a run to ``stream``: feed each channel's messages in order (:meth:`feed`), then :meth:`finish`.

    ``scene`` (None when the recording's scene no longer loads) gives the mechanism and the spike
    detector's parameters; ``frame_ns``, how much simulated time between two frames of the mechanism
    (``recordings.mechanism.Mechanism``; None: every step)."""

    def __init__(self, stream: rr.RecordingStream, specs: list[ChannelSpec], scene: Scene | None,
                 frame_ns: int | None = None) -> None:
        self.stream = stream
        sources = list(dict.fromkeys(s.source for s in specs if s.source != "manager"))
        self.series: dict[str, list[Series]] = {
            spec.topic: series_of(spec, PALETTE[sources.index(spec.source) % len(PALETTE)]
                                  if spec.source in sources else PALETTE[7]) for spec in specs}
        self.specs = {spec.topic: spec for spec in specs}
        self.scene = scene
        self.mechanism = Mechanism(scene, frame_ns) if scene is not None else None
        self._columns: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        self._residual: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}  # bond → (times [ns], δP) of the status
        self._colors = {source: PALETTE[i % len(PALETTE)] for i, source in enumerate(sources)}
        # mechanism entity → (kind, labels, colour, steps, times, shapes per step); its labels sent yet
        self._shapes: dict[str, tuple[str, list, tuple, list, list, list]] = {}
        self._labelled: set[str] = set()
        self.extent: np.ndarray | None = None  # [x min, x max, y min, y max] of the mechanism so far [m]
        self.timing_p99 = 0.0  # the highest 99th percentile of a step-timing series in a fed batch so far [µs]
        # an energy-controlled run's macro-steps (manager.scheme.energy_step): a series of their lengths, from the
        # status times; the time of the last status fed (t_0 before the first)
        varying = scene is not None and scene.manager.step_control == "energy"
        self.macro_step = Series(_path(MACRO_STEP[0]), _path(MACRO_STEP[0]), f"{MACRO_STEP[1]} [ms]", f"{MACRO_STEP[1]} [ms]",
                                 "ms", PALETTE[0], -1, 1e-6) if varying else None
        self._last_status_ns = 0
        self._macro_steps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def start(self) -> None:
        """Log each series' name, colour and unit (static); call once the stream's sinks are set."""
        every = [s for group in self.series.values() for s in group]
        if self.macro_step is not None:
            every.append(self.macro_step)
        for series in every:
            self.stream.log(series.entity, rr.SeriesLines(colors=[series.color], names=[series.label], widths=[1.5]),
                            rr.AnyValues(unit=series.unit), static=True)

    def panels(self) -> dict[str, str]:
        """Panel origin (an entity path) → panel title, in the order of :data:`QUANTITIES` then the status's."""
        found = {s.origin: s.panel for group in self.series.values() for s in group}
        if self.macro_step is not None:
            found[self.macro_step.origin] = self.macro_step.panel
        order = [_path(q[0]) for q in (*QUANTITIES.values(), *STATUS_QUANTITIES.values(), STEP_TIMING, WALL_TIME)]
        return dict(sorted(found.items(), key=lambda item: order.index(item[0]) if item[0] in order else len(order)))

    def feed(self, topic: str, steps: np.ndarray, times: np.ndarray, values: np.ndarray) -> None:
        """The next messages of channel ``topic`` of its kind (:data:`PLOTTED`): their steps, times [ns] and
        values (a row each; of a command, its polynomial's first row first)."""
        spec = self.specs[topic]
        if not steps.size:
            return
        values = values[:, :len(spec.names)]
        if spec.role == "outputs" and self.mechanism is not None:
            self.mechanism.outputs(spec.source, steps, values)
        self._columns.setdefault(topic, []).append((steps, times, values))
        for series in self.series[topic]:
            if series.origin == _path(STEP_TIMING[0]) and np.isfinite(values[:, series.column]).any():
                p99 = np.nanpercentile(values[:, series.column], 99) * series.scale
                self.timing_p99 = max(self.timing_p99, float(p99))
        if spec.role == "status" and self.macro_step is not None:
            self._macro_steps.append((steps, times, np.diff(times, prepend=self._last_status_ns)))
            self._last_status_ns = int(times[-1])
        if spec.role == "status":
            for j, name in enumerate(spec.names):
                if name.startswith("delta_p."):
                    self._residual.setdefault(name.split(".", 1)[1], []).append((times, values[:, j]))

    def commands(self, ordered: list[tuple[str, bytes]]) -> None:
        """Wire commands (subsystem, message) step by step, for the mechanism."""
        if self.mechanism is not None:
            for name, wire in ordered:
                for frame in self.mechanism.command(name, wire):
                    self._draw(frame)

    def flush(self) -> None:
        """Send what was fed since the last flush."""
        for topic, parts in self._columns.items():
            steps, times, values = (np.concatenate(column) for column in zip(*parts))
            for series in self.series[topic]:
                column = values[:, series.column]
                kept = ~np.isnan(column)  # a multi-rate bond is not evaluated at every step: no gap in its line
                self.stream.send_columns(series.entity, indexes=self._indexes(steps[kept], times[kept]),
                                         columns=rr.Scalars.columns(scalars=column[kept] * series.scale))
        self._columns = {}
        if self._macro_steps:
            steps, times, lengths = (np.concatenate(column) for column in zip(*self._macro_steps))
            self.stream.send_columns(self.macro_step.entity, indexes=self._indexes(steps, times),
                                     columns=rr.Scalars.columns(scalars=lengths * self.macro_step.scale))
            self._macro_steps = []
        self._send_shapes()

    @staticmethod
    def _indexes(steps: np.ndarray, times: np.ndarray) -> list:
        return [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("sim_time", duration=times.astype("timedelta64[ns]"))]

    def _at(self, step: int, time_ns: int) -> None:
        self.stream.set_time("step", sequence=step)
        self.stream.set_time("sim_time", duration=np.timedelta64(time_ns, "ns"))

    def _draw(self, frame: Frame) -> None:
        """Keep the shapes of a frame of the mechanism, per entity, until the next flush."""
        shapes = []
        for name, sketch in frame.sketches.items():
            if sketch.boxes:
                shapes.append((_path("mechanism", name, "bodies"), "boxes", list(sketch.boxes.values()),
                               list(sketch.boxes), self._colors.get(name, PALETTE[7])))
            if sketch.paths:
                shapes.append((_path("mechanism", name, "elements"), "strips", list(sketch.paths.values()),
                               list(sketch.paths), self._colors.get(name, PALETTE[7])))
        for name, (line, arrow) in frame.couplings.items():
            if line is not None:
                shapes.append((_path("mechanism", "couplings", name), "strips", [line], [name], (90, 90, 90)))
            if arrow is not None:
                shapes.append((_path("mechanism", "forces", name), "arrows", [arrow], [f"{name} force"],
                               (214, 39, 40)))
        corners = [np.array([c, (c[0] - h[0], c[1] - h[1]), (c[0] + h[0], c[1] + h[1])])
                   for sketch in frame.sketches.values() for c, h in sketch.boxes.values()]
        points = np.concatenate(corners + [p for sketch in frame.sketches.values() for p in sketch.paths.values()]
                                or [np.zeros((0, 2))])
        if points.size:
            low, high = points.min(axis=0), points.max(axis=0)
            if self.extent is not None:
                low, high = np.minimum(low, self.extent[::2]), np.maximum(high, self.extent[1::2])
            self.extent = np.array([low[0], high[0], low[1], high[1]])
        for entity, kind, items, labels, color in shapes:
            if entity not in self._shapes:
                self._shapes[entity] = (kind, labels, color, [], [], [])
            _, _, _, steps, times, kept = self._shapes[entity]
            steps.append(frame.step)
            times.append(frame.time_ns)
            kept.append(items)

    def _send_shapes(self) -> None:
        """Send the kept shapes, y turned to point down as Rerun's 2-D views draw it (so up is up)."""
        flip = np.array([1.0, -1.0])
        for entity, (kind, labels, color, steps, times, kept) in self._shapes.items():
            if not steps:
                continue
            archetype = {"boxes": rr.Boxes2D, "strips": rr.LineStrips2D, "arrows": rr.Arrows2D}[kind]
            if entity not in self._labelled:
                self.stream.log(entity, archetype.from_fields(labels=labels, colors=[color]), static=True)
                self._labelled.add(entity)
            lengths = [len(items) for items in kept]
            items = [item for frame_items in kept for item in frame_items]
            if kind == "boxes":
                columns = rr.Boxes2D.columns(centers=np.array([c for c, _ in items]) * flip,
                                             half_sizes=[h for _, h in items])
            elif kind == "strips":
                columns = rr.LineStrips2D.columns(strips=[strip * flip for strip in items])
            else:
                columns = rr.Arrows2D.columns(origins=np.array([o for o, _ in items]) * flip,
                                              vectors=np.array([v for _, v in items]) * flip)
            self.stream.send_columns(entity, indexes=self._indexes(np.array(steps), np.array(times)),
                                     columns=columns.partition(lengths))
            steps.clear()
            times.clear()
            kept.clear()

    def gap(self, last_step: int, next_step: int, macro_step_ns: int) -> None:
        """The live view fell behind: the steps between ``last_step`` and ``next_step`` did not reach it. Said on
        the timeline; the mechanism stops there (its copies would need every command)."""
        self.stream.set_time("sim_time", duration=np.timedelta64(last_step * macro_step_ns, "ns"))
        self.stream.log(EVENTS, rr.TextLog(f"the live view fell behind the run: steps {last_step + 1}–{next_step - 1} "
                                           "are not shown, and the mechanism stops here (the replay of a recording "
                                           "shows both)", level="WARN"))
        self.mechanism = None

    def events(self, outcome: str, last_step: int, steps: int, macro_step_ns: int
               ) -> tuple[list[tuple[int, str, str]], list[tuple[float, float]]]:
        """The events of what was fed — (time [ns], level, text) of every flagged residual-power spike and of
        how the run ended — and the intervals to highlight [s]: the spikes, and a run that stopped before its
        last step from there on."""
        found, flagged = [], []
        spikes = self.scene.manager.spikes if self.scene is not None else None
        for bond, parts in self._residual.items():
            times, p_res = (np.concatenate(column) for column in zip(*parts))
            intervals = (spike_intervals(times * 1e-9, p_res, spikes.window, spikes.threshold, spikes.merge_gap)
                         if spikes is not None and times.size else [])
            for interval in intervals:
                found.append((round(interval.start * 1e9), "WARN",
                              f"bond {bond}: residual-power spike {interval.start:.4g}–{interval.end:.4g} s, peak "
                              f"δP {interval.peak:.4g} W at {interval.peak_time:.4g} s"))
                flagged.append((interval.start, interval.end))
        end_ns = last_step * macro_step_ns
        if last_step < steps:
            flagged.append((end_ns * 1e-9, steps * macro_step_ns * 1e-9))
            found.append((end_ns, "ERROR", f"the run stopped at step {last_step} of {steps} (t = {end_ns * 1e-9:g} s): "
                                           f"{outcome}"))
        else:
            found.append((end_ns, "INFO", f"run {outcome}"))
        return found, flagged

    def last_frames(self) -> None:
        """Draw the frames the mechanism still holds: no more commands come."""
        if self.mechanism is not None:
            for frame in self.mechanism.finish():
                self._draw(frame)

    def finish(self, events: list[tuple[int, str, str]]) -> None:
        """Send the rest and ``events`` (see :meth:`events`)."""
        self.flush()
        for time_ns, level, text in events:
            self.stream.set_time("sim_time", duration=np.timedelta64(time_ns, "ns"))
            self.stream.log(EVENTS, rr.TextLog(text, level=level))


def ordered_commands(channels: dict[str, list[bytes]]) -> list[tuple[str, bytes]]:
    """Every subsystem's commands (wire messages, each list in order) merged step by step."""
    def keyed(name: str, wires: list[bytes]):
        return ((int.from_bytes(wire[8:16], "little", signed=True), name, wire) for wire in wires)
    return [(name, wire) for _, name, wire in heapq.merge(*(keyed(n, w) for n, w in channels.items()),
                                                         key=lambda item: item[0])]


def blueprint(view: RunView, highlight: tuple[float, float] | None = None) -> rrb.Blueprint:
    """The mechanism and the events beside one time-series panel per quantity and unit (per signal for a
    dimensionless one), the whole run in view on the ``sim_time`` timeline; ``highlight`` [s] is selected on the
    time panel.

    A mechanism that moves along a line (more than ``WIDE`` times wider than high) gets a strip across
    the top instead of a square at the left. The step-timing panel opens on 0 to ``TIMING_RANGE`` times
    the 99th percentile, so that a step the machine's load delayed a thousandfold does not flatten the
    others (zoom out, or double-click, to see it)."""
    whole_run = rrb.VisibleTimeRange("sim_time", start=rrb.TimeRangeBoundary.infinite(),
                                     end=rrb.TimeRangeBoundary.infinite())
    timing = rrb.ScalarAxis(range=(0.0, TIMING_RANGE * view.timing_p99)) if view.timing_p99 > 0 else None
    plots = [rrb.TimeSeriesView(origin=origin, name=title, time_ranges=[whole_run],
                                plot_legend=rrb.PlotLegend(visible=True),
                                axis_y=timing if origin == _path(STEP_TIMING[0]) else None)
             for origin, title in view.panels().items()]
    events = rrb.TextLogView(origin=EVENTS, name="events")
    mechanism, wide = None, False
    if view.mechanism is not None and view.mechanism.drawn:
        bounds = None
        if view.extent is not None:  # what the mechanism covered, with a margin; y down as Rerun draws it
            x0, x1, y0, y1 = view.extent
            margin = 0.1 * max(x1 - x0, y1 - y0, 1.0)
            bounds = rrb.VisualBounds2D(x_range=[x0 - margin, x1 + margin], y_range=[-y1 - margin, -y0 + margin])
            wide = x1 - x0 > WIDE * (y1 - y0)
        mechanism = rrb.Spatial2DView(origin=MECHANISM, name="mechanism [m]", visual_bounds=bounds)
    if wide:
        layout = rrb.Vertical(mechanism, rrb.Horizontal(events, rrb.Grid(*plots, grid_columns=3), column_shares=[1, 4]),
                              row_shares=[1, 3])
    else:
        left = [mechanism, events] if mechanism is not None else [events]
        layout = rrb.Horizontal(rrb.Vertical(*left, row_shares=[3, 1][:len(left)]), rrb.Grid(*plots, grid_columns=2),
                                column_shares=[2, 3])
    selection = None if highlight is None else rr.AbsoluteTimeRange(
        start=np.timedelta64(round(highlight[0] * 1e9), "ns"), end=np.timedelta64(round(highlight[1] * 1e9), "ns"))
    return rrb.Blueprint(layout, rrb.TimePanel(timeline="sim_time", time_selection=selection, state="expanded"),
                         collapse_panels=True)
