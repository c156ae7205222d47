"""The language's solids as closed triangle meshes, in metres, centred on their own origin.

Built with numpy, without trimesh (a scene of solids alone never imports it) and without mesh
booleans: a plate with an opening is a ring between the opening's outline and the plate's,
swept out radially from the centre (both outlines are star-shaped about it), then given its
thickness. Each mesh is closed and its triangles wind outward.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.geometry.model import FloatArray, IntArray

SEGMENTS = 48  # around a cylinder or a round opening: under 0.3 % short of the true circle


def box(size: tuple[float, float, float]) -> tuple[FloatArray, IntArray]:
    """A box of ``size`` (x, y, z), centred."""
    half = np.asarray(size, dtype=float) / 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
        dtype=np.int64,
    )  # fmt: skip
    return corners * half, faces


def cylinder(radius: float, length: float) -> tuple[FloatArray, IntArray]:
    """A cylinder along its own +Y, centred, with flat caps."""
    theta = np.linspace(0, 2 * math.pi, SEGMENTS, endpoint=False)
    ring = np.stack([radius * np.cos(theta), np.zeros_like(theta), -radius * np.sin(theta)], 1)
    half = np.array([0.0, length / 2, 0.0])
    bottom = ring - half
    top = ring + half
    centres = np.array([[0, -length / 2, 0], [0, length / 2, 0]])
    vertices = np.concatenate([bottom, top, centres])
    i = np.arange(SEGMENTS)
    j = (i + 1) % SEGMENTS
    n = SEGMENTS
    side = np.concatenate([np.stack([i, j, j + n], 1), np.stack([i, j + n, i + n], 1)])
    caps = np.concatenate(
        [np.stack([np.full(n, 2 * n), j, i], 1), np.stack([np.full(n, 2 * n + 1), i + n, j + n], 1)]
    )
    return vertices, np.concatenate([side, caps]).astype(np.int64)


def plate(
    size: tuple[float, float, float],
    opening: tuple[str, float | tuple[float, float]] | None = None,
) -> tuple[FloatArray, IntArray]:
    """A plate of width x, height y and thickness z (its normal is its own +Z), centred, with
    an optional centred opening: ("round", diameter) or ("rect", (width, height))."""
    width, height, thickness = size
    if opening is None:
        return box(size)
    hw, hh = width / 2, height / 2
    kind, dims = opening
    angles = [np.linspace(0, 2 * math.pi, SEGMENTS, endpoint=False), _corner_angles(hw, hh)]
    if kind == "rect":
        ow, oh = dims  # type: ignore[misc]
        angles.append(_corner_angles(ow / 2, oh / 2))
    theta = np.unique(np.concatenate(angles) % (2 * math.pi))
    outer = _rect_outline(theta, hw, hh)
    if kind == "rect":
        inner = _rect_outline(theta, ow / 2, oh / 2)
    else:
        r = float(dims) / 2  # type: ignore[arg-type]
        inner = np.stack([r * np.cos(theta), r * np.sin(theta)], 1)
    return _ring(inner, outer, thickness)


def _corner_angles(hw: float, hh: float) -> FloatArray:
    a = math.atan2(hh, hw)
    return np.array([a, math.pi - a, math.pi + a, 2 * math.pi - a])


def _rect_outline(theta: FloatArray, hw: float, hh: float) -> FloatArray:
    """Where rays from the centre at ``theta`` leave the rectangle of half sizes hw, hh."""
    c, s = np.cos(theta), np.sin(theta)
    with np.errstate(divide="ignore"):
        t = np.minimum(
            np.where(np.abs(c) > 1e-12, hw / np.abs(c), np.inf),
            np.where(np.abs(s) > 1e-12, hh / np.abs(s), np.inf),
        )
    return np.stack([t * c, t * s], 1)


def _ring(inner: FloatArray, outer: FloatArray, thickness: float) -> tuple[FloatArray, IntArray]:
    """The closed solid between two outlines (K, 2) at the same angles, ``thickness`` deep."""
    k = len(inner)
    z = thickness / 2
    layers = [np.column_stack([pts, np.full(k, h)]) for pts in (inner, outer) for h in (z, -z)]
    vertices = np.concatenate(layers)  # inner top, inner bottom, outer top, outer bottom
    it, ib, ot, ob = (np.arange(k) + m * k for m in range(4))
    nxt = np.roll(np.arange(k), -1)
    quads = [
        (it, ot, ot[nxt], it[nxt]),  # top face, +Z
        (ib[nxt], ob[nxt], ob, ib),  # bottom face, -Z
        (ob, ob[nxt], ot[nxt], ot),  # outer wall
        (ib[nxt], ib, it, it[nxt]),  # the opening's wall
    ]
    tris = []
    for a, b, c, d in quads:
        tris += [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]
    return vertices, np.concatenate(tris).astype(np.int64)


def frame_from_axis(axis: FloatArray, along: int) -> FloatArray:
    """A rotation whose column ``along`` is the unit ``axis``: the cylinder's axis (1, its +Y)
    or the plate's normal (2, its +Z). A plate's width (+X) stays horizontal, its height in
    the vertical plane; a horizontal plate's width runs along the scene's X."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    up = np.array([0.0, 1.0, 0.0])
    if along == 2:
        x = np.cross(up, a)
        if np.linalg.norm(x) < 1e-9:
            x = np.array([1.0, 0.0, 0.0])
        x /= np.linalg.norm(x)
        y = np.cross(a, x)
        return np.column_stack([x, y, a])
    ref = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    z = np.cross(ref, a)
    z /= np.linalg.norm(z)
    x = np.cross(a, z)
    return np.column_stack([x, a, z])
