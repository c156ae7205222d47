"""Does a hand, a forearm or a tool fit through the opening it reaches through?

A part passing through an opening moves along its own axis, so what it needs is a free prism:
its cross-section (a hand: an ellipse, its breadth by its thickness, the flattened oval of a
hand across the knuckles; a forearm or a tool: a circle), swept along the stretch of the axis
that has to pass. A round opening as wide as the hand's breadth lets the hand through, as it
does a real hand turned flat. Here that stretch is measured on
a posed frame: the equipment's edges near it (each triangle edge sampled every few millimetres,
and the corners) are projected onto the plane across the axis, and the cross-section is turned
about the axis to find the orientation that keeps every projected point outside; the largest
scale of the cross-section that fits (1 or more: it passes) and the edge that stops it are the
answer. A thin plate's opening is found whatever its thickness (its rim is an edge).

Only an *opening* counts: the projected edges must surround the axis (a point within
``ENCLOSE`` times the cross-section's larger radius in each of ``SECTORS`` directions around
it). Equipment on one side only (a bench under a forearm, a wall beside a hand) is a matter of
clearance and collision, not of an opening's size: the part could move away from it; and the
axis crossing a surface is a collision of the motion, not a verdict on the design (and a
flat face's own triangulation would surround it with edges).

Geometry only: the sizes come from the caller (the manikin's hand breadth, a glove allowance),
and so does the stretch (the fingertips, which hold the part, are left out by the caller).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mtlc.geometry.model import FloatArray
from mtlc.geometry.rays import RayScene

EDGE_STEP = 0.004  # m between the points sampled along an edge
MAX_EDGE_POINTS = 64  # per edge (a 25 cm edge near a hand is sampled every 4 mm)
TURNS = 72  # orientations of an ellipse tried over half a turn (2.5 degrees apart)
SECTORS = 12  # directions around the axis an opening's rim must be found in (30 degrees each)
ENCLOSE = 2.0  # ...within this many times the cross-section's larger radius


@dataclass(frozen=True)
class Passage:
    """How a cross-section passes a stretch of axis: ``scale`` is the largest multiple of the
    needed size that fits (>= 1: it passes; ``inf``: no opening around the axis), ``face`` the
    triangle that stops a larger one (-1: none)."""

    scale: float
    face: int

    @property
    def fits(self) -> bool:
        return self.scale >= 1.0


def passage(
    scene: RayScene, start: FloatArray, end: FloatArray, breadth: float, thickness: float
) -> Passage:
    """The free prism along the segment ``start``-``end`` for an ellipse ``breadth`` x
    ``thickness`` (m, its diameters; equal for a circle) centred on it, turned at will."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    axis = end - start
    length = float(np.linalg.norm(axis))
    if length < 1e-9 or len(scene) == 0:
        return Passage(math.inf, -1)
    if np.isfinite(scene.blocked(start[None], end[None]).distance[0]):
        return Passage(math.inf, -1)  # the axis crosses a surface: a collision, not an opening
    unit = axis / length
    half = 0.5 * max(breadth, thickness)
    points, faces = _edge_points(scene, start, end, ENCLOSE * half)
    if len(points) == 0:
        return Passage(math.inf, -1)
    rel = points - start
    along = rel @ unit
    keep = (along >= 0.0) & (along <= length)
    across = rel[keep] - along[keep, None] * unit
    faces = faces[keep]
    if len(across) == 0:
        return Passage(math.inf, -1)
    u, v = _basis(unit)
    x, y = across @ u, across @ v
    near = np.hypot(x, y) <= ENCLOSE * half
    sector = (np.floor((np.arctan2(y, x) + math.pi) / (2 * math.pi) * SECTORS)).astype(int)
    if len(np.unique(np.minimum(sector[near], SECTORS - 1))) < SECTORS:
        return Passage(math.inf, -1)  # not surrounded: no opening to pass
    if breadth == thickness:  # a circle: the nearest point sets the scale
        r = np.hypot(x, y)
        k = int(np.argmin(r))
        return Passage(float(r[k] / (0.5 * breadth)), int(faces[k]))
    theta = np.linspace(0.0, math.pi, TURNS, endpoint=False)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    # the scale at which each point touches the ellipse turned by theta
    touch = np.hypot((x * c + y * s) / (0.5 * breadth), (-x * s + y * c) / (0.5 * thickness))
    nearest = np.argmin(touch, axis=1)  # (TURNS,)
    scales = touch[np.arange(TURNS), nearest]
    best = int(np.argmax(scales))
    return Passage(float(scales[best]), int(faces[nearest[best]]))


def _basis(unit: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors across ``unit``, at right angles."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(unit[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(unit, ref)
    u /= np.linalg.norm(u)
    return u, np.cross(unit, u)


def _edge_points(
    scene: RayScene, start: FloatArray, end: FloatArray, half: float
) -> tuple[FloatArray, np.ndarray]:
    """Points along the edges of the triangles whose boxes meet the segment's box grown by
    ``half``, and the triangle of each."""
    low = np.minimum(start, end) - half
    high = np.maximum(start, end) + half
    near = np.flatnonzero(((scene.high >= low) & (scene.low <= high)).all(axis=1))
    if len(near) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    v0 = scene.origin[near]
    corners = np.stack([v0, v0 + scene.edge1[near], v0 + scene.edge2[near]], axis=1)  # (T, 3, 3)
    a = corners.reshape(-1, 3)
    b = np.roll(corners, -1, axis=1).reshape(-1, 3)
    face = np.repeat(near, 3)
    count = np.clip(np.ceil(np.linalg.norm(b - a, axis=1) / EDGE_STEP), 1, MAX_EDGE_POINTS)
    count = count.astype(np.int64)
    edge = np.repeat(np.arange(len(a)), count)
    first = np.cumsum(count) - count
    step = (np.arange(len(edge)) - first[edge]) / count[edge]
    points = a[edge] + step[:, None] * (b[edge] - a[edge])
    return points, face[edge]
