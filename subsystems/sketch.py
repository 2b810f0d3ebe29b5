"""How a model draws itself: a sketch in the plane [m], from its state, for the animated replay.

A model that can be drawn has ``sketch(z, w) -> Sketch``: boxes (point masses), paths (springs,
dampers, links, cylinders) and the anchors of its coupling points, in its own coordinates. A sketch
``on_line`` is of bodies that move along x only (the point masses); the viewer gives each such
subsystem a lane of its own below the others (``LANE`` apart per body), so that bodies that start at
the same x never cover each other. A sketch in the plane (pendulum, links, the crane arm) is drawn
where its coordinates say. The viewer joins the anchors of a coupling's two points and draws the
coupling force as an arrow at the motion side's point (``recordings.mechanism``). A model without
``sketch`` is not drawn; a user's model may define one (docs/models.md).

Nothing here knows how the sketch is shown.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

LANE = 1.0  # [m] between the lanes of two bodies on a line
BOX = 0.2  # [m] half the side of a point mass's box
ZIGZAG = (6, 0.1)  # a spring's teeth and their half width [m]
_ALONG = np.linspace(0.0, 1.0, 2 * ZIGZAG[0] + 3)[:, None]  # where each corner of the zigzag is along the spring
_ACROSS = np.array([0.0, 0.0] + [ZIGZAG[1], -ZIGZAG[1]] * ZIGZAG[0] + [0.0])[:, None]  # and across it


@dataclass(frozen=True)
class Anchor:
    """Where a coupling point is drawn; a scalar coupling signal acts along ``direction`` (a unit vector)."""

    point: str
    position: tuple[float, float]
    direction: tuple[float, float] = (1.0, 0.0)


@dataclass
class Sketch:
    """A model's drawing at one instant: labelled boxes (centre, half size) and paths, and its anchors."""

    boxes: dict[str, tuple[tuple[float, float], tuple[float, float]]] = field(default_factory=dict)
    paths: dict[str, np.ndarray] = field(default_factory=dict)  # label → (k, 2) points
    anchors: dict[str, Anchor] = field(default_factory=dict)
    on_line: bool = False  # bodies on a line: drawn in a lane of their own

    def box(self, label: str, center, half_size=(BOX, BOX)) -> None:
        self.boxes[label] = ((float(center[0]), float(center[1])), (float(half_size[0]), float(half_size[1])))

    def path(self, label: str, *points) -> None:
        self.paths[label] = np.array(points, dtype=np.float64).reshape(-1, 2)

    def spring(self, label: str, a, b) -> None:
        """A zigzag from ``a`` to ``b`` (``ZIGZAG``)."""
        ax, ay, bx, by = float(a[0]), float(a[1]), float(b[0]), float(b[1])
        dx, dy = bx - ax, by - ay
        length = (dx * dx + dy * dy) ** 0.5 or 1.0
        self.paths[label] = np.array([ax, ay]) + _ALONG * np.array([dx, dy]) + _ACROSS * np.array([-dy, dx]) / length

    def anchor(self, point: str, position, direction=(1.0, 0.0)) -> None:
        self.anchors[point] = Anchor(point, (float(position[0]), float(position[1])),
                                     (float(direction[0]), float(direction[1])))
