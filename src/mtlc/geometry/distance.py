"""Distance from capsules to triangle meshes, batched over frames (docs/collision.md).

A capsule is an axis segment and a radius; its signed clearance to a mesh is the distance from
its axis to the mesh's triangles less its radius: positive is the gap, negative how deep the
capsule's surface goes past the mesh's surface (at most its radius, when the axis touches or
crosses a triangle). The mesh is its surface: a capsule wholly inside a closed solid without
touching its surface reads as clear (the manikin enters equipment from outside, so a limb inside
a solid crossed its surface on the way in, and was reported there).

Two implementations of the same quantity:

* ``MeshIndex``: a bounding-volume hierarchy (OBB-RSS) built once per mesh by coal (the
  maintained fork of FCL, formerly hpp-fcl); each query asks coal for the
  distance from the axis (a capsule of radius 0) to the mesh. coal was chosen over python-fcl on
  this machine's measurements (bench/collision.py, docs/collision.md): the same distances and
  query times, builds 1.3-1.4x faster, signed distance where python-fcl answers -1.
* ``brute_force_distance``: every segment against every triangle in numpy, the baseline the
  library is tested and benchmarked against (``O(S·T)``: small meshes only).

The meshes come as plain arrays (vertices (V, 3) m in the scene's frame, faces (F, 3) indices),
so this module knows no file format and no scene model.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body.capsules import segment_distance

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Mesh = tuple[FloatArray, IntArray]  # vertices (V, 3), faces (F, 3)

_EPS = 1e-12
_BRUTE_CHUNK = 2_000_000  # segment-triangle pairs per numpy block (about 1 GB of temporaries)


# -- brute force ----------------------------------------------------------------------------


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.einsum("...c,...c->...", a, b)


def point_segment_distance(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """(...,) distance from points ``p`` to segments ``a``-``b`` (all (..., 3), broadcast)."""
    d = b - a
    t = np.clip(_dot(p - a, d) / np.maximum(_dot(d, d), _EPS), 0.0, 1.0)
    return np.linalg.norm(p - a - t[..., None] * d, axis=-1)


def segment_segment_distance(
    p1: FloatArray, q1: FloatArray, p2: FloatArray, q2: FloatArray
) -> FloatArray:
    """(...,) closest distance between segments ``p1``-``q1`` and ``p2``-``q2`` (broadcast):
    the self-contact model's ``segment_distance`` (Ericson 5.1.9) on the flattened pairs."""
    shape = np.broadcast_shapes(p1.shape, q1.shape, p2.shape, q2.shape)
    flat = [np.broadcast_to(x, shape).reshape(-1, 3) for x in (p1, q1, p2, q2)]
    return segment_distance(*flat).reshape(shape[:-1])


def point_triangle_distance(p: FloatArray, tri: FloatArray) -> FloatArray:
    """(...,) distance from points ``p`` (..., 3) to triangles ``tri`` (..., 3, 3): to the
    plane where the point projects inside the triangle, else to the nearest edge."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    n = np.cross(b - a, c - a)
    n_len = np.linalg.norm(n, axis=-1)
    unit = n / np.maximum(n_len, _EPS)[..., None]
    height = _dot(p - a, unit)
    foot = p - height[..., None] * unit
    inside = (
        (n_len > _EPS)  # a degenerate triangle is its edges
        & (_dot(np.cross(b - a, foot - a), n) >= 0.0)
        & (_dot(np.cross(c - b, foot - b), n) >= 0.0)
        & (_dot(np.cross(a - c, foot - c), n) >= 0.0)
    )
    edges = np.minimum(
        np.minimum(point_segment_distance(p, a, b), point_segment_distance(p, b, c)),
        point_segment_distance(p, c, a),
    )
    return np.where(inside, np.abs(height), edges)


def segment_crosses_triangle(p: FloatArray, q: FloatArray, tri: FloatArray) -> NDArray[np.bool_]:
    """(...,) whether segment ``p``-``q`` passes through triangle ``tri`` (Möller-Trumbore)."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    d = q - p
    e1, e2 = b - a, c - a
    h = np.cross(d, e2)
    det = _dot(e1, h)
    ok = np.abs(det) > _EPS
    inv = 1.0 / np.where(ok, det, 1.0)
    s = p - a
    u = inv * _dot(s, h)
    qv = np.cross(s, e1)
    v = inv * _dot(d, qv)
    t = inv * _dot(e2, qv)
    return ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t >= 0.0) & (t <= 1.0)


def segment_triangle_distance(p: FloatArray, q: FloatArray, tri: FloatArray) -> FloatArray:
    """(...,) closest distance between segments ``p``-``q`` (..., 3) and triangles (..., 3, 3):
    zero where the segment crosses the triangle, else the least of its two ends to the
    triangle and the segment to the triangle's three edges."""
    ends = np.minimum(point_triangle_distance(p, tri), point_triangle_distance(q, tri))
    for i in range(3):
        ends = np.minimum(
            ends, segment_segment_distance(p, q, tri[..., i, :], tri[..., (i + 1) % 3, :])
        )
    return np.where(segment_crosses_triangle(p, q, tri), 0.0, ends)


def brute_force_distance(a: FloatArray, b: FloatArray, mesh: Mesh) -> FloatArray:
    """(S,) distance from each segment ``a``-``b`` (S, 3) to the nearest triangle of ``mesh``,
    every pair in numpy (in blocks of ``_BRUTE_CHUNK`` pairs)."""
    vertices, faces = mesh
    tri = np.asarray(vertices, float)[np.asarray(faces, np.int64)]  # (T, 3, 3)
    a, b = np.reshape(np.asarray(a, float), (-1, 3)), np.reshape(np.asarray(b, float), (-1, 3))
    out = np.full(len(a), np.inf)
    if len(tri) == 0:
        return out
    rows = max(1, _BRUTE_CHUNK // len(tri))
    for lo in range(0, len(a), rows):
        sl = slice(lo, lo + rows)
        d = segment_triangle_distance(a[sl, None, :], b[sl, None, :], tri[None, :, :, :])
        out[sl] = d.min(axis=1)
    return out


# -- the collision library --------------------------------------------------------------------


def _segment_frames(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(S, 3, 3) rotations taking +Z to ``b - a``, (S, 3) mid-points and (S,) lengths: where
    the libraries' capsules (centred, along their own Z) must be put to lie on the segments.
    Computed for all segments at once: per-segment numpy calls cost more than the query."""
    d = b - a
    length = np.linalg.norm(d, axis=-1)
    z = np.where(length[:, None] > _EPS, d / np.maximum(length, _EPS)[:, None], [0.0, 0.0, 1.0])
    helper = np.where(np.abs(z[:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=-1), 0.5 * (a + b), length


def _triangle_edges(vertices: FloatArray, faces: IntArray) -> tuple[FloatArray, FloatArray]:
    """(E, 3) ends of the distinct edges of triangles ``faces`` (each edge once)."""
    pairs = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return vertices[pairs[:, 0]], vertices[pairs[:, 1]]


OUTLINE_ANGLE = 30.0  # deg between two triangles' normals: their shared edge is an outline


def _outline_keys(vertices: FloatArray, faces: IntArray) -> IntArray:
    """Sorted keys (``v0 * V + v1``, v0 < v1) of a mesh's outline edges (``MeshIndex.outline``)."""
    if not len(faces):
        return np.zeros(0, dtype=np.int64)
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), _EPS)
    pairs = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    keys = pairs[:, 0] * len(vertices) + pairs[:, 1]
    owner = np.tile(np.arange(len(faces)), 3)
    order = np.argsort(keys, kind="stable")
    keys, owner = keys[order], owner[order]
    unique, first, count = np.unique(keys, return_index=True, return_counts=True)
    outline = count != 2
    two = np.flatnonzero(count == 2)
    cos = _dot(normal[owner[first[two]]], normal[owner[first[two] + 1]])
    outline[two] = cos < np.cos(np.radians(OUTLINE_ANGLE))
    return unique[outline]


def crossing_depth(
    a: FloatArray,
    b: FloatArray,
    tri: FloatArray,
    outline: FloatArray,
    gap: Callable[[FloatArray], FloatArray],
) -> float:
    """The deepest of segments ``a``-``b`` (E, 3) passing through triangles ``tri`` (T, 3, 3)
    (ends strictly on either side of its plane, through its inside, not along an edge: 0 if
    none does): each crossing as deep as the shorter way out, back along the segment (its
    nearer end's distance ``gap`` (points (K, 3) -> (K,)) to the mesh crossed, as
    ``MeshIndex.through_depth`` for a capsule's axis) or across the surface to its nearest
    ``outline`` edge (K, 2, 3; none: along the segment only)."""
    if not len(a) or not len(tri):
        return 0.0
    p0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    normal = np.cross(e1, e2)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), _EPS)
    sa = _dot(a[:, None, :] - p0[None], normal[None])  # (E, T) signed heights of the ends
    sb = _dot(b[:, None, :] - p0[None], normal[None])
    tol = 1e-6
    cross = (sa * sb < 0.0) & (np.abs(sa) > tol) & (np.abs(sb) > tol)
    e, t = np.nonzero(cross)
    if not e.size:
        return 0.0
    x = a[e] + (sa[e, t] / (sa[e, t] - sb[e, t]))[:, None] * (b[e] - a[e])
    # inside the triangle: barycentric coordinates of the crossing point
    w = x - p0[t]
    d00, d01, d11 = _dot(e1[t], e1[t]), _dot(e1[t], e2[t]), _dot(e2[t], e2[t])
    d20, d21 = _dot(w, e1[t]), _dot(w, e2[t])
    den = np.maximum(d00 * d11 - d01 * d01, _EPS)
    v = (d11 * d20 - d01 * d21) / den
    u = (d00 * d21 - d01 * d20) / den
    margin = 1e-9  # on an edge of the triangle: a tangent touch (a cylinder's seam on a wall)
    inside = (v > margin) & (u > margin) & (u + v < 1.0 - margin)
    if not inside.any():
        return 0.0
    x, e = x[inside], e[inside]
    k = np.unique(e)
    ends = gap(np.concatenate([a[k], b[k]]))
    back = np.zeros(len(a))
    back[k] = np.minimum(ends[: k.size], ends[k.size :])
    along = back[e]
    if len(outline):
        across = point_segment_distance(
            x[:, None, :], outline[None, :, 0, :], outline[None, :, 1, :]
        ).min(axis=1)
        along = np.minimum(along, across)
    return float(along.max())


class MeshIndex:
    """One mesh's bounding-volume hierarchy, for segment-distance queries.

    ``library`` is "coal" (the default, see the module doc) or "fcl" (python-fcl, kept for the
    comparison in bench/collision.py). Build once per mesh (a 100 k-triangle mesh: tens of ms),
    query as often as needed.
    """

    def __init__(self, vertices: FloatArray, faces: IntArray, library: str = "coal") -> None:
        self.library = library
        v = np.ascontiguousarray(vertices, dtype=np.float64)
        f = np.ascontiguousarray(faces, dtype=np.int64)
        self.n_triangles = len(f)
        self._vertices, self._faces = v, f
        self._outline: IntArray | None = None  # keys of the outline edges, found when asked
        used = v[np.unique(f)] if len(f) else np.zeros((1, 3))
        self.lower, self.upper = used.min(axis=0), used.max(axis=0)  # the bounding box
        if library == "coal":
            import coal

            model = coal.BVHModelOBBRSS()
            model.beginModel(len(f), len(v))
            model.addVertices(v)
            model.addTriangles(f)
            model.endModel()
            self._coal = coal
            self._model = model
            self._identity = coal.Transform3s()
        elif library == "fcl":
            import fcl

            model = fcl.BVHModel()
            model.beginModel(len(v), len(f))
            model.addSubModel(v, f)
            model.endModel()
            self._fcl = fcl
            self._object = fcl.CollisionObject(model, fcl.Transform())
        else:
            raise ValueError(f"unknown collision library {library!r}: 'coal' or 'fcl'")

    def segment_distance(
        self, a: FloatArray, b: FloatArray, horizon: float | None = None
    ) -> FloatArray:
        """(S,) distance from each segment ``a``-``b`` (S, 3) to the mesh (0 where it touches or
        crosses a triangle). With a ``horizon`` (m), a segment farther than it from the mesh's
        bounding box is not queried: its distance to the box, a lower bound over the horizon,
        stands in (most of a body is far from most equipment most of the time)."""
        a, b = np.reshape(np.asarray(a, float), (-1, 3)), np.reshape(np.asarray(b, float), (-1, 3))
        out = np.empty(len(a))
        if self.n_triangles == 0:
            out.fill(np.inf)
            return out
        query = self._coal_distance if self.library == "coal" else self._fcl_distance
        rot, mid, length = _segment_frames(a, b)
        ask = np.ones(len(a), dtype=bool)
        if horizon is not None:
            outside = np.maximum(np.maximum(self.lower - mid, mid - self.upper), 0.0)
            out[:] = np.maximum(np.linalg.norm(outside, axis=-1) - 0.5 * length, 0.0)
            ask = out <= horizon
        for i in np.flatnonzero(ask):
            out[i] = query(rot[i], mid[i], float(length[i]))
        # in contact the libraries answer 0, -1 (fcl) or a degenerate penetration (coal, a
        # segment in a triangle's plane): the axis touches the mesh
        return np.where(np.isfinite(out) & (out > 0.0), out, 0.0)

    def through_depth(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """(S,) how far segments ``a``-``b`` that pass through a triangle of the mesh stick out:
        the distance of the nearer end to the mesh (0 for a segment that does not pass
        through one, or only touches). A capsule whose axis crosses the surface is in by its
        radius and that much more: the distance alone stops at the radius, and a hand through a
        3 mm panel up to the knuckles reads as one lying on it. coal only (python-fcl: 0)."""
        a, b = np.reshape(np.asarray(a, float), (-1, 3)), np.reshape(np.asarray(b, float), (-1, 3))
        out = np.zeros(len(a))
        if self.library != "coal" or self.n_triangles == 0:
            return out
        coal = self._coal
        rot, mid, length = _segment_frames(a, b)
        request = coal.CollisionRequest()
        request.num_max_contacts = 256
        owner, faces = [], []  # (segment, triangle) pairs the axes meet
        for i in range(len(a)):
            result = coal.CollisionResult()
            shape = coal.Capsule(0.0, float(length[i]))
            coal.collide(shape, coal.Transform3s(rot[i], mid[i]), self._model, self._identity,
                         request, result)  # fmt: skip
            met = [c.b2 for c in result.getContacts() if c.b2 >= 0]
            owner += [i] * len(met)
            faces += met
        if not faces:
            return out
        who = np.asarray(owner)
        tri = self._vertices[self._faces[np.asarray(faces)]]
        crossing = np.zeros(len(a), dtype=bool)
        crossing[who[segment_crosses_triangle(a[who], b[who], tri)]] = True
        k = np.flatnonzero(crossing)
        if k.size:  # all the crossing segments' ends in one query
            ends = np.concatenate([a[k], b[k]])
            gap = self.segment_distance(ends, ends)
            out[k] = np.minimum(gap[: k.size], gap[k.size :])
        return out

    def touched_face(self, a: FloatArray, b: FloatArray, radius: float) -> int | None:
        """The triangle a capsule (axis ``a``-``b``, ``radius``) goes deepest into, to name the
        part of a model it hits (``SceneModel.parts``); None when it touches none, or with
        python-fcl. Asked once per finding: a collision query with the capsule's radius (the
        distance query's answer in contact has no triangle)."""
        if self.library != "coal" or self.n_triangles == 0:
            return None
        coal = self._coal
        rot, mid, length = _segment_frames(
            np.reshape(np.asarray(a, float), (1, 3)), np.reshape(np.asarray(b, float), (1, 3))
        )
        request, result = coal.CollisionRequest(), coal.CollisionResult()
        request.num_max_contacts = 64
        shape = coal.Capsule(float(radius), float(length[0]))
        coal.collide(shape, coal.Transform3s(rot[0], mid[0]), self._model, self._identity,
                     request, result)  # fmt: skip
        contacts = result.getContacts()
        if not contacts:
            return None
        return int(min(contacts, key=lambda c: (c.penetration_depth, c.b2)).b2)

    def placed_depth(self, other: MeshIndex, placements: FloatArray) -> tuple[FloatArray, IntArray]:
        """How deep this mesh, moved by each of ``placements`` (N, 4, 4), goes into ``other``
        (where it is): (N,) depths (m) and (N,) the ``other`` triangle met first (-1: none).

        A carried part is a mesh, not a capsule: the library finds the triangle pairs that
        meet (one BVH-BVH query per placement); then each edge of this mesh's triangles met,
        and each outline edge of the other's (``outline``), that passes through a triangle of
        the other mesh (``crossing_depth``) is as deep as the
        shorter way out: back along the edge (its nearer end's distance to the mesh crossed)
        or across the surface it passes to that surface's nearest outline edge. A panel pushed 4 cm into a wall reads 40 mm, one
        lying against it 0, one grazing a wall's corner by 2 mm reads 2 mm (not the length of
        its edge). coal only (python-fcl: zeros)."""
        n = len(placements)
        depth, face = np.zeros(n), np.full(n, -1, dtype=np.int64)
        if self.library != "coal" or other.library != "coal" or not len(self._faces):
            return depth, face
        coal = self._coal
        request = coal.CollisionRequest()
        request.num_max_contacts = 256
        mine_outline = self.outline(np.arange(len(self._faces)))
        for i, m in enumerate(np.asarray(placements, dtype=float)):
            result = coal.CollisionResult()
            coal.collide(self._model, coal.Transform3s(m[:3, :3], m[:3, 3]), other._model,
                         other._identity, request, result)  # fmt: skip
            pairs = [(c.b1, c.b2) for c in result.getContacts() if c.b1 >= 0 and c.b2 >= 0]
            if not pairs:
                continue
            mine = np.unique([p[0] for p in pairs])
            theirs = np.unique([p[1] for p in pairs])
            face[i] = int(theirs[0])
            rot, move = m[:3, :3], m[:3, 3]
            # this mesh's edges through the other's triangles, in the other's frame
            a, b = _triangle_edges(self._vertices, self._faces[mine])
            tri = other._vertices[other._faces[theirs]]
            outline = other.outline(theirs)
            into = crossing_depth(a @ rot.T + move, b @ rot.T + move, tri, outline,
                                  lambda p: other.segment_distance(p, p))  # fmt: skip
            # the other's outline edges through this mesh's triangles, in this mesh's frame
            # (not its faces' diagonals: one lying along a curved part reads as deep as the
            # part's seam to its rim)
            c, d = outline[:, 0], outline[:, 1]
            mine_tri = self._vertices[self._faces[mine]]
            back = crossing_depth((c - move) @ rot, (d - move) @ rot, mine_tri, mine_outline,
                                  lambda p: self.segment_distance(p, p))  # fmt: skip
            depth[i] = max(into, back)
        return depth, face

    def outline(self, faces: IntArray) -> FloatArray:
        """(K, 2, 3) the outline edges among the edges of triangles ``faces``: edges of one
        triangle only, or between two that meet at more than ``OUTLINE_ANGLE`` (a box's
        edges, a cylinder's rims; not a face's diagonal or a cylinder's side seams)."""
        if self._outline is None:
            self._outline = _outline_keys(self._vertices, self._faces)
        f = self._faces[np.asarray(faces, dtype=np.int64)]
        pairs = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        pairs = np.unique(pairs, axis=0)
        keep = np.isin(pairs[:, 0] * len(self._vertices) + pairs[:, 1], self._outline)
        return self._vertices[pairs[keep]]

    def _coal_distance(self, rot: FloatArray, mid: FloatArray, length: float) -> float:
        coal = self._coal
        pose = coal.Transform3s(rot, mid)
        return float(
            coal.distance(
                coal.Capsule(0.0, length),
                pose,
                self._model,
                self._identity,
                coal.DistanceRequest(),
                coal.DistanceResult(),
            )
        )

    def _fcl_distance(self, rot: FloatArray, mid: FloatArray, length: float) -> float:
        fcl = self._fcl
        seg = fcl.CollisionObject(fcl.Capsule(0.0, length), fcl.Transform(rot, mid))
        return float(fcl.distance(seg, self._object, fcl.DistanceRequest(), fcl.DistanceResult()))


def build_indices(meshes: Mapping[str, Mesh], library: str = "coal") -> dict[str, MeshIndex]:
    """A ``MeshIndex`` per named mesh, in name order."""
    return {name: MeshIndex(*meshes[name], library=library) for name in sorted(meshes)}


def capsule_clearance(
    a: FloatArray,
    b: FloatArray,
    radius: Any,
    meshes: Mapping[str, Mesh] | Mapping[str, MeshIndex],
    library: str = "coal",
    horizon: float | None = None,
) -> tuple[FloatArray, tuple[str, ...]]:
    """(..., M) signed clearance (m) of capsules with axes ``a``-``b`` (..., 3) and radius
    (broadcast to ``a.shape[:-1]``) to each mesh, and the mesh names in column order (sorted):
    the axis's distance to the mesh less the radius (negative: how deep the surface goes in).

    ``meshes`` maps names to (vertices, faces) or to indices already built (build them once
    when the same meshes are asked about again); ``horizon`` as in
    ``MeshIndex.segment_distance`` (beyond it, a lower bound)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    shape = a.shape[:-1]
    r = np.broadcast_to(np.asarray(radius, float), shape).reshape(-1)
    names = tuple(sorted(meshes))
    cols = []
    for name in names:
        m = meshes[name]
        index = m if isinstance(m, MeshIndex) else MeshIndex(*m, library=library)
        cols.append(index.segment_distance(a.reshape(-1, 3), b.reshape(-1, 3), horizon) - r)
    out = np.stack(cols, axis=-1) if cols else np.zeros((len(r), 0))
    return out.reshape(*shape, len(names)), names
