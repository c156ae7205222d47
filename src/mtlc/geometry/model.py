"""A scene's geometry as triangle meshes in the scene frame (metres, Y up), and how a mesh
file's own frame is placed there.

The collision and visibility code reads ``SceneModel.vertices``, ``.faces`` and ``.name``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# which axis of a node's own frame is the site's normal: +Y, the axis a Blender empty's arrow
# (+Z in Blender) becomes in a +Y-up glTF export, and "up" for a node left unrotated
NODE_NORMAL_AXIS = 1
# the file's up axis -> the scene's +Y, keeping the frame right-handed
UP_AXES: dict[str, FloatArray] = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),  # (x, y, z) -> (x, z, -y)
    "x": np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),  # (x, y, z) -> (-y, x, z)
}
FAR_AWAY = 1000.0  # m: geometry beyond this distance from the origin is a units mistake


@dataclass(frozen=True, eq=False)
class SceneModel:
    """One model or solid of a scene, placed. ``nodes``: named node -> (position, unit normal)
    in the scene frame; ``source``/``sha256``: the file and its content hash (None for a
    solid); ``solid``: "box", "cylinder" or "plate" (None for a model)."""

    name: str
    vertices: FloatArray  # (V, 3) m, scene frame
    faces: IntArray  # (F, 3) indices into vertices
    nodes: dict[str, tuple[FloatArray, FloatArray]]
    source: str | None
    sha256: str | None
    solid: str | None
    transform: FloatArray = field(default_factory=lambda: np.eye(4))  # own frame -> scene
    parameters: dict[str, Any] = field(default_factory=dict)  # a solid's size, radius...
    # a glTF file's parts: (node name, index of its first face), in face order; what a ray
    # meets is named by them (mtlc.geometry.rays); empty for a solid or a one-part file
    parts: tuple[tuple[str, int], ...] = ()

    @property
    def triangles(self) -> int:
        return int(self.faces.shape[0])

    def record(self) -> dict[str, Any]:
        """What the IR JSON says of it (docs/ir.md): no vertices, the file and its hash, or the
        solid's parameters (SI units), and the placement as a row-major 4x4 matrix."""
        out: dict[str, Any] = {"name": self.name, "kind": self.solid or "model"}
        if self.solid is None:
            out.update(path=self.source, sha256=self.sha256)
        out.update(self.parameters)
        out["transform"] = [[float(x) for x in row] for row in self.transform]
        out["triangles"] = self.triangles
        return out

    def part_of(self, face: int | None) -> str | None:
        """The glTF node whose geometry holds ``face`` (None for a solid, a one-part file or
        no face): what a finding names besides the model."""
        if face is None or not self.parts:
            return None
        firsts = [first for _, first in self.parts]
        k = bisect.bisect_right(firsts, face) - 1
        return self.parts[k][0] if k >= 0 else None

    def farthest(self) -> float:
        """The largest distance of a vertex from the scene's origin (m)."""
        if len(self.vertices) == 0:
            return 0.0
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        return float(np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi))))


def rotation_xyz(angles: tuple[float, float, float]) -> FloatArray:
    """Rotations about X, then Y, then Z (radians), as one matrix: the convention of a site's
    `frame` (mtlc.passes.lower.frame_matrix), so `rotate` and `frame` read alike."""
    rx, ry, rz = angles
    cx, sx, cy, sy = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry)
    cz, sz = math.cos(rz), math.sin(rz)
    X = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return X @ Y @ Z


def placement(
    at: tuple[float, float, float] = (0.0, 0.0, 0.0),
    rotate: tuple[float, float, float] = (0.0, 0.0, 0.0),
    scale: float = 1.0,
    up: str = "y",
) -> FloatArray:
    """The 4x4 matrix from a file's frame to the scene's: scale to metres, turn the file's up
    axis to +Y, rotate (X, Y, Z), then move to ``at``."""
    m = np.eye(4)
    m[:3, :3] = rotation_xyz(rotate) @ UP_AXES[up] * scale
    m[:3, 3] = at
    return m


def place_points(matrix: FloatArray, points: FloatArray) -> FloatArray:
    """(N, 3) points through a 4x4 matrix, at once."""
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def place_nodes(
    matrix: FloatArray, nodes: dict[str, FloatArray]
) -> dict[str, tuple[FloatArray, FloatArray]]:
    """Each node's frame (4x4, in the file) -> (position, unit normal) in the scene: the origin,
    and the node's +Y axis (NODE_NORMAL_AXIS) as a direction."""
    out: dict[str, tuple[FloatArray, FloatArray]] = {}
    for name, frame in nodes.items():
        world = matrix @ frame
        axis = world[:3, NODE_NORMAL_AXIS]
        norm = float(np.linalg.norm(axis))
        normal = axis / norm if norm > 0 else np.array([0.0, 1.0, 0.0])
        out[name] = (world[:3, 3].copy(), normal)
    return out
