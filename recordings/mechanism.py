"""The mechanism of a run, animated: its commands re-executed on copies of its subsystems, sketched.

The subsystems' states are not in a recording, but their commands are, and a subsystem is
deterministic: executing a subsystem's commands in order on a copy built from the recording's scene
gives back its replies bit for bit (``zencosim replay --verify`` checks the same of the whole run)
and its state after each one. After every reply with outputs, the model sketches itself
(``subsystems.sketch``); the sketches of bodies on a line are moved into lanes of their own; every
coupling is a line between the anchors of its two points, and a force–displacement coupling's force
is an arrow at its motion side's point (the force the coupling exerts there: the force side's output
``f`` as the motion side receives it), scaled so that the largest force seen so far is ``ARROW`` long.

Bodies on a line are drawn at a *lane scale* (``lane_scale``): their lanes, boxes, springs' teeth and force
arrows are that many times their sketched size, so that they stay visible beside the distance they travel
(two_mass_damped's masses swing over about 18 m: at the sketch's 1 m lanes and 0.4 m boxes they were specks
with their labels on top of each other). The scale follows the x span that the run's bodies on a line have
covered in every step up to the frame, so it only grows, in a few steps (1, 2, 5, 10, …): x stays as the
model says.

Both the replay and the live view feed the commands step by step (each subsystem's in its order) and
the recorded outputs of the couplings' force sides; a subsystem whose
model cannot be built here (an FMU file that is missing) or has no ``sketch`` is not drawn. Every
command is executed (the state needs them all), but only every ``every``-th step is sketched: the replay
draws every step, the live view a frame per ``LIVE_FRAME_NS`` of simulated time (what a viewer can
show while the run goes; the frames it draws are the replay's, bit for bit, because the arrows' scale
is the largest force of every step so far, drawn or not).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from zencosim.manager.assembly import plan_scene
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.scene.load import Scene
from zencosim.manager.wire.protocol import HEADER, Kind
from zencosim.subsystems.sketch import LANE, Sketch

ARROW = 0.5 * LANE  # [m] length of the largest coupling-force arrow (times the lane scale on a line)
SPAN_LANES = 4.0  # bodies on a line: their lanes are at least 1 / SPAN_LANES of their x span apart
LIVE_FRAME_NS = 10_000_000  # [ns] of simulated time between two frames of the live view (100 per simulated second)


@dataclass
class Frame:
    """What to draw at one communication point: the sketches of the subsystems that reported there, and the
    couplings whose two sides are both drawn: line (2, 2) and force arrow (origin, vector) or None."""

    step: int
    time_ns: int
    sketches: dict[str, Sketch] = field(default_factory=dict)
    couplings: dict[str, tuple[np.ndarray | None, tuple[np.ndarray, np.ndarray] | None]] = field(default_factory=dict)


class Mechanism:
    """Copies of a run's drawable subsystems; :meth:`command` executes one of their commands."""

    def __init__(self, scene: Scene, frame_ns: int | None = None) -> None:
        """``frame_ns``: sketch a frame per this much simulated time [ns] (whole communication points of
        every subsystem); None: every step."""
        plan, subsystems = plan_scene(scene)
        common = math.lcm(*(s.ratio for s in plan.subsystems))  # steps at which every subsystem reports
        self.every = common * max(1, round((frame_ns or 0) / (common * plan.base_step_ns)))
        drawable = [s.name for s in plan.subsystems if hasattr(subsystems[s.name].model, "sketch")]
        self._endpoints = endpoints(plan, subsystems, drawable)
        self._subsystems = subsystems
        self._lanes: dict[str, float] = {}  # a subsystem on a line → the y of its first lane at scale 1 [m]
        lane = 0.0
        for name in drawable:  # each subsystem on a line below the ones before it
            first = subsystems[name].model.sketch(subsystems[name].z, subsystems[name].w)
            if first.on_line:
                self._lanes[name] = -lane
                lane += max(len(first.boxes), 1) * LANE
        self.drawn = tuple(drawable)
        bonds = {bond.name: bond for bond in plan.bonds}
        self._couplings = []  # (name, side a, side b, (force side, its force outputs) or None)
        for name, coupling in scene.couplings.items():
            (sub_a, point_a), (sub_b, point_b) = coupling.sides().values()  # force side first
            if sub_b in drawable:
                bond = bonds.get(name)
                force = None if bond is None else (plan.subsystems[bond.force_side].name, bond.force_output)
                self._couplings.append((name, (sub_a, point_a), (sub_b, point_b), force))
        self._force_outputs: dict[str, list[list[int]]] = {}  # force side → the force outputs of each of its couplings
        for *_, force in self._couplings:
            if force is not None:
                self._force_outputs.setdefault(force[0], []).append(list(force[1]))
        self._pending: dict[int, Frame] = {}
        self._latest: dict[str, int] = {}  # the last step each drawn subsystem reported
        self._outputs: dict[str, deque[tuple[int, np.ndarray]]] = {name: deque() for name in self._force_outputs}
        self._largest_force = 0.0  # of every step up to the last frame completed [N]
        self._spans: dict[str, deque[tuple[int, float, float]]] = {name: deque() for name in self._lanes}
        self._line_span = (math.inf, -math.inf)  # x min, x max of the bodies on a line up to the last frame [m]

    def command(self, name: str, wire: bytes) -> list[Frame]:
        """Execute a command of subsystem ``name`` (ignored when it is not drawn); return the frames that this
        completes: those before the last point every drawn subsystem has reported (so the frames do not depend
        on how the commands of different subsystems interleave)."""
        endpoint = self._endpoints.get(name)
        if endpoint is None:
            return []
        reply = endpoint.handle(wire)
        _, kind, _, _, step, time_ns, _ = HEADER.unpack_from(reply)
        if kind != Kind.OUTPUT:
            return []
        drawn, on_line = step % self.every == 0, name in self._spans
        if drawn or on_line:  # a body on a line: every step, for the lane scale
            subsystem = self._subsystems[name]
            sketch = subsystem.model.sketch(subsystem.z, subsystem.w)
            if on_line:
                xs = [c[0] for c, _ in sketch.boxes.values()] + [x for p in sketch.paths.values() for x in p[:, 0]]
                if xs:
                    self._spans[name].append((step, min(xs), max(xs)))
            if drawn:
                self._pending.setdefault(step, Frame(step, time_ns)).sketches[name] = sketch
        self._latest[name] = step
        if len(self._latest) < len(self._endpoints):
            return []
        reported = min(self._latest.values())  # every drawn subsystem has gone past the frames before this
        return [self._complete(done) for done in sorted(s for s in self._pending if s < reported)]

    def outputs(self, name: str, steps: np.ndarray, values: np.ndarray) -> None:
        """Recorded OUTPUTs of subsystem ``name`` (drawn or not; a row of ``values`` per step of ``steps``): the
        force of its couplings at those steps (kept only for a coupling's force side)."""
        queue = self._outputs.get(name)
        if queue is not None:
            queue.extend(zip(steps.tolist(), values))

    def finish(self) -> list[Frame]:
        """The frames still pending, in order."""
        return [self._complete(step) for step in sorted(self._pending)]

    def _complete(self, step: int) -> Frame:
        """The frame at ``step`` with its couplings: a line where both sides are drawn, an arrow where the
        motion side is drawn and the force side's output is known."""
        frame = self._pending.pop(step)
        forces = self._forces_until(step)
        scale = self._lane_scale_until(step)
        for name, sketch in frame.sketches.items():
            if name in self._lanes:
                _place_on_lane(sketch, self._lanes[name], scale)
        for name, (sub_a, point_a), (sub_b, point_b), force in self._couplings:
            if sub_b not in frame.sketches:
                continue
            b = frame.sketches[sub_b].anchors[point_b]
            line = None
            if sub_a in frame.sketches:
                line = np.array([frame.sketches[sub_a].anchors[point_a].position, b.position])
            arrow = None
            outputs = None if force is None else forces.get(force[0])
            if outputs is not None:
                f = outputs[list(force[1])]
                vector = f[0] * np.array(b.direction) if f.size == 1 else f[:2]
                length = ARROW * (scale if sub_b in self._lanes else 1.0)
                per_newton = length / self._largest_force if self._largest_force > 0 else 0.0
                arrow = (np.array(b.position), vector * per_newton)
            frame.couplings[name] = (line, arrow)
        return frame

    def _forces_until(self, step: int) -> dict[str, np.ndarray]:
        """Take the force sides' outputs up to ``step`` into the largest force so far (the magnitude of a
        coupling's force: along its point's unit direction, or in the plane); return those at ``step``."""
        at = {}
        for source, queue in self._outputs.items():
            while queue and queue[0][0] <= step:
                reported, values = queue.popleft()
                for outputs in self._force_outputs[source]:
                    f = values[outputs]
                    self._largest_force = max(self._largest_force, float(abs(f[0]) if f.size == 1 else np.hypot(*f[:2])))
                if reported == step:
                    at[source] = values
        return at


    def _lane_scale_until(self, step: int) -> float:
        """Take the x spans of the bodies on a line up to ``step`` into the span so far; its lane scale."""
        low, high = self._line_span
        for queue in self._spans.values():
            while queue and queue[0][0] <= step:
                _, x_min, x_max = queue.popleft()
                low, high = min(low, x_min), max(high, x_max)
        self._line_span = (low, high)
        return lane_scale(high - low)


def lane_scale(span: float) -> float:
    """The smallest of 1, 2, 5, 10, 20, … that draws lanes at least ``span`` / ``SPAN_LANES`` apart."""
    needed = span / (SPAN_LANES * LANE)
    if not 1.0 < needed < math.inf:  # NaN too: bodies that left the finite numbers are drawn at their sketch's size
        return 1.0
    decade = 10.0 ** math.floor(math.log10(needed))
    return next(m * decade for m in (1.0, 2.0, 5.0, 10.0) if m * decade >= needed)


def _place_on_lane(sketch: Sketch, lane_y: float, scale: float) -> None:
    """Move a sketch of bodies on a line to its lane (``lane_y`` at scale 1), its y and sizes times ``scale``."""
    dy = lane_y * scale
    sketch.boxes = {k: ((c[0], c[1] * scale + dy), (h[0] * scale, h[1] * scale)) for k, (c, h) in sketch.boxes.items()}
    stretch = np.array([1.0, scale])
    sketch.paths = {k: p * stretch + (0.0, dy) for k, p in sketch.paths.items()}
    for point, anchor in sketch.anchors.items():
        sketch.anchor(point, (anchor.position[0], anchor.position[1] * scale + dy), anchor.direction)
