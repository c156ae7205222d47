"""Rays and line segments against a scene's triangles: what the eyes see, how wide a way is.

Visibility (a line from the eyes to a site through the equipment) and access openings (how far
the free space reaches across a hand's path) both ask where a ray first meets a triangle. The
scenes are small (an example has a few thousand triangles, a CAD model up to MAX_TRIANGLES) and a
question asks a few hundred rays, so the test is Möller–Trumbore in numpy over the triangles
whose bounding boxes meet the rays' bounding box, in chunks that bound the memory: no Python
loop over triangles, no library (embree is not in every registry; trimesh's own ray code needs
rtree and gives no face-to-part name), and the same answer on every machine.

Each triangle keeps the name of what it belongs to: ``model`` for a solid or a mesh file
without named parts, ``model.node`` for a glTF node's geometry (mtlc.geometry.load), so a
finding can say what is in the way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mtlc.geometry.model import FloatArray, IntArray, SceneModel

EPS = 1e-12  # a ray parallel to a triangle's plane
EDGE = 1e-9  # barycentric slack: a ray through a seam between two triangles meets them
CHUNK = 1 << 20  # rays x triangles tested at once (about 100 MB of float64 temporaries)


@dataclass(frozen=True)
class Hits:
    """Per ray: the distance to the first triangle met (``inf``: none within reach) and that
    triangle's index in the scene (-1: none)."""

    distance: FloatArray
    face: IntArray


class RayScene:
    """Every triangle of a scene's models, flattened once, with its part's name."""

    def __init__(self, models: Sequence[SceneModel]) -> None:
        corners: list[FloatArray] = []
        owner: list[IntArray] = []
        self.names: list[str] = []
        for model in models:
            if len(model.faces) == 0:
                continue
            corners.append(model.vertices[model.faces])  # (F, 3, 3)
            starts = [(0, model.name)] + [
                (first, f"{model.name}.{node}") for node, first in model.parts
            ]
            starts.sort(key=lambda s: s[0])
            part = np.zeros(len(model.faces), dtype=np.int64)
            for first, name in starts:
                part[first:] = len(self.names)
                self.names.append(name)
            owner.append(part)
        tri = np.concatenate(corners) if corners else np.zeros((0, 3, 3))
        self.origin = tri[:, 0]
        self.edge1 = tri[:, 1] - tri[:, 0]
        self.edge2 = tri[:, 2] - tri[:, 0]
        self.low = tri.min(axis=1)
        self.high = tri.max(axis=1)
        self.part = np.concatenate(owner) if owner else np.zeros(0, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.origin)

    def name(self, face: int) -> str:
        """What triangle ``face`` belongs to (``model`` or ``model.node``)."""
        return self.names[int(self.part[face])]

    def cast(self, origins: FloatArray, directions: FloatArray, reach: FloatArray | float) -> Hits:
        """The first triangle each ray meets within ``reach`` (m) of its origin, ``directions``
        unit vectors (R, 3). A ray starting on a surface does not see it (distances below 1e-9
        are not hits)."""
        origins = np.asarray(origins, dtype=float).reshape(-1, 3)
        directions = np.asarray(directions, dtype=float).reshape(-1, 3)
        reach = np.broadcast_to(np.asarray(reach, dtype=float), (len(origins),))
        best = np.full(len(origins), np.inf)
        face = np.full(len(origins), -1, dtype=np.int64)
        if len(origins) == 0 or len(self) == 0:
            return Hits(best, face)
        ends = origins + directions * reach[:, None]
        low = np.minimum(origins, ends).min(axis=0)
        high = np.maximum(origins, ends).max(axis=0)
        near = np.flatnonzero(((self.high >= low) & (self.low <= high)).all(axis=1))
        if len(near) == 0:
            return Hits(best, face)
        step = max(1, CHUNK // len(origins))
        for k in range(0, len(near), step):
            tris = near[k : k + step]
            t = self._intersect(origins, directions, tris)  # (R, T)
            t[(t < 1e-9) | (t > reach[:, None])] = np.inf
            j = np.argmin(t, axis=1)
            d = t[np.arange(len(origins)), j]
            better = d < best
            best[better] = d[better]
            face[better] = tris[j[better]]
        return Hits(best, face)

    def blocked(self, starts: FloatArray, ends: FloatArray, spare: float = 0.0) -> Hits:
        """For each segment from ``starts`` to ``ends`` (S, 3): the first triangle crossed
        before the last ``spare`` metres of it (a site on a surface is not hidden by that
        surface), its distance from the start."""
        starts = np.asarray(starts, dtype=float).reshape(-1, 3)
        line = np.asarray(ends, dtype=float).reshape(-1, 3) - starts
        length = np.linalg.norm(line, axis=1)
        unit = line / np.maximum(length, 1e-12)[:, None]
        return self.cast(starts, unit, np.maximum(length - spare, 0.0))

    def _intersect(self, o: FloatArray, d: FloatArray, tris: IntArray) -> FloatArray:
        """Möller–Trumbore, rays x triangles: the distance along each ray to each triangle's
        plane where the ray crosses inside the triangle, else ``inf``."""
        e1, e2, v0 = self.edge1[tris], self.edge2[tris], self.origin[tris]
        p = np.cross(d[:, None, :], e2[None, :, :])  # (R, T, 3)
        det = np.einsum("tk,rtk->rt", e1, p)
        ok = np.abs(det) > EPS
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o[:, None, :] - v0[None, :, :]
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1[None, :, :])
        v = np.einsum("rk,rtk->rt", d, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
        # a ray along the edge two triangles share meets each at u or v = 0 give or take the
        # rounding, and missed both: it went through a plate at the seam of its triangles
        inside = ok & (u >= -EDGE) & (v >= -EDGE) & (u + v <= 1 + EDGE)
        return np.where(inside, t, np.inf)
