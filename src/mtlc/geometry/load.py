"""Read a model file (glTF 2.0, OBJ, STL) into one triangle mesh and its named node frames.

trimesh reads the formats; it is imported here, on the first model a scene names, so checking
files without models never pays for it (about 0.8 s of CPU). Every failure is a ``ModelError``
with its diagnostic code: the caller reports it at the `model` line, never a traceback.
Big meshes stay cheap: everything is numpy arrays, nothing loops over triangles in Python.
"""

from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass
from pathlib import Path, PurePath, PureWindowsPath

import numpy as np

from mtlc.geometry.model import FloatArray, IntArray

FORMATS = {".glb": "glb", ".gltf": "gltf", ".obj": "obj", ".stl": "stl"}
FIXED_FRAME = frozenset({"glb", "gltf"})  # glTF fixes its units (m) and axes (+Y up)
MAX_TRIANGLES = 2_000_000  # 1 M triangles of STL: 1.7 s CPU, 0.7 of it importing trimesh
MAX_FILE_BYTES = 256 * 1024 * 1024


class ModelError(Exception):
    """A model file mtlc cannot use: its diagnostic code, message and help."""

    def __init__(self, code: str, message: str, help: str | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.message = message
        self.help = help


@dataclass(frozen=True, eq=False)
class MeshFile:
    """A mesh file as read, in its own frame and units. ``nodes``: every named node's frame
    (4x4, in the file's frame); ``markers``: those without geometry, which `sites from` takes."""

    path: Path
    format: str
    sha256: str
    vertices: FloatArray
    faces: IntArray
    nodes: dict[str, FloatArray]
    markers: tuple[str, ...]
    parts: tuple[tuple[str, int], ...] = ()  # each node with geometry: its first face


def resolve(written: str, folder: Path) -> Path:
    """The file a model's path names: relative to ``folder`` (the .mtask file's), and inside it
    (MT0008). Checked on the text, so a link inside the folder that the user put there works."""
    if not written.strip() or "\0" in written:
        what = "is empty" if not written.strip() else "holds a NUL character"
        raise ModelError("MT0005", f"the model's path {what}", help="name the model's file")
    pure = PurePath(written.replace("\\", "/"))
    if pure.is_absolute() or PureWindowsPath(written).drive or written.startswith(("/", "\\")):
        raise ModelError(
            "MT0008",
            f"the model's path `{written}` is absolute or names a drive",
            help="write it relative to the folder of this .mtask file",
        )
    normal = os.path.normpath(pure.as_posix())
    if normal == ".." or normal.startswith("../"):
        raise ModelError(
            "MT0008",
            f"the model's path `{written}` leads outside the folder of this .mtask file",
            help="keep the model in the procedure's folder or below it",
        )
    return folder / normal


_CACHE: dict[str, tuple[tuple[int, int], MeshFile]] = {}  # by file: (mtime, size), mesh


def read_mesh(path: Path) -> MeshFile:
    """The mesh in ``path``; kept while the file's size and modification time hold."""
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise ModelError(
            "MT0006",
            f"mtlc cannot read `{path.name}`: not a glTF (.glb, .gltf), OBJ or STL file",
            help="export the model as .glb (glTF 2.0 binary)",
        )
    try:
        stat = path.stat()
    except OSError as exc:
        raise ModelError("MT0005", f"model file `{path}` not found", help=_os_help(exc)) from None
    if not path.is_file():
        raise ModelError("MT0005", f"`{path}` is not a file")
    if stat.st_size > MAX_FILE_BYTES:
        raise ModelError(
            "MT0007",
            f"model file `{path.name}` is {stat.st_size / 2**20:.0f} MB, over the "
            f"{MAX_FILE_BYTES / 2**20:.0f} MB limit",
            help="simplify (decimate) the model, or keep only the parts near the task",
        )
    key, stamp = str(path.resolve()), (stat.st_mtime_ns, stat.st_size)
    cached = _CACHE.get(key)
    if cached is None or cached[0] != stamp:  # one version a file: `serve` recompiles on edits
        cached = _CACHE[key] = (stamp, _read(path, fmt))
    return cached[1]


def _os_help(exc: OSError) -> str:
    return f"the path is relative to the .mtask file's folder ({exc.strerror})"


def _read(path: Path, fmt: str) -> MeshFile:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ModelError("MT0005", f"model file `{path}` cannot be read: {exc.strerror}") from None
    digest = hashlib.sha256(data).hexdigest()
    import trimesh  # here: only scenes with a model pay for importing it

    try:
        if fmt in FIXED_FRAME:
            vertices, faces, nodes, markers, parts = _read_scene(trimesh, path)
        elif fmt == "stl":  # the arrays straight from the parser: a Trimesh costs 10x more
            from trimesh.exchange.stl import load_stl

            vertices, faces = _arrays(_Arrays(load_stl(io.BytesIO(data))))
            nodes, markers, parts = {}, (), ()
        else:
            mesh = trimesh.load(str(path), file_type=fmt, force="mesh", process=False)
            vertices, faces = _arrays(mesh)
            nodes, markers, parts = {}, (), ()
    except ModelError:
        raise
    except Exception as exc:  # trimesh raises many kinds on a broken file
        if "escapes resolver root" in str(exc):  # a .gltf's buffer or image named outside
            raise ModelError(
                "MT0008",
                f"model file `{path.name}` names a file outside its folder",
                help="keep a .gltf's .bin and textures beside it, or export a .glb",
            ) from None
        raise ModelError(
            "MT0006",
            f"model file `{path.name}` cannot be read as {fmt.upper()}: {_short(exc)}",
            help="open it in a mesh viewer, or export it again",
        ) from None
    if len(faces) == 0:
        raise ModelError("MT0006", f"model file `{path.name}` has no triangles")
    if len(faces) > MAX_TRIANGLES:
        raise ModelError(
            "MT0007",
            f"model `{path.name}` has {len(faces):,} triangles, over the limit of "
            f"{MAX_TRIANGLES:,}",
            help="simplify (decimate) the model, or keep only the parts near the task",
        )
    if not np.isfinite(vertices).all():
        raise ModelError("MT0006", f"model file `{path.name}` has coordinates that are not numbers")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ModelError("MT0006", f"model file `{path.name}` has triangles with missing corners")
    return MeshFile(path, fmt, digest, vertices, faces, nodes, markers, parts)


class _Arrays:
    """A parser's dict of arrays, read like a mesh."""

    def __init__(self, parsed: dict[str, object]) -> None:
        self.vertices = parsed.get("vertices", np.zeros((0, 3)))
        self.faces = parsed.get("faces", np.zeros((0, 3)))


def _short(exc: Exception) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[:200]


def _arrays(mesh: object) -> tuple[FloatArray, IntArray]:
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1:] != (3,):
        vertices = vertices.reshape(-1, 3)
    if faces.size == 0:
        faces = np.zeros((0, 3), dtype=np.int64)
    return vertices, faces.reshape(-1, 3)


def _read_scene(
    trimesh: object, path: Path
) -> tuple[
    FloatArray, IntArray, dict[str, FloatArray], tuple[str, ...], tuple[tuple[str, int], ...]
]:
    """A glTF scene: every node's geometry placed by the scene graph, as one mesh; every named
    node's frame; the nodes without geometry (markers); where each node's faces begin."""
    scene = trimesh.load(str(path), force="scene", process=False)  # type: ignore[attr-defined]
    graph = scene.graph
    with_geometry = set(graph.nodes_geometry)
    nodes: dict[str, FloatArray] = {}
    markers: list[str] = []
    for name in sorted(graph.nodes):
        if name == graph.base_frame:
            continue
        matrix, _geometry = graph[name]
        nodes[str(name)] = np.asarray(matrix, dtype=np.float64)
        if name not in with_geometry:
            markers.append(str(name))
    verts: list[FloatArray] = []
    faces: list[IntArray] = []
    parts: list[tuple[str, int]] = []
    offset = first = 0
    for name in sorted(with_geometry):
        matrix, geometry = graph[name]
        v, f = _arrays(scene.geometry.get(geometry))
        if len(f) == 0:
            continue  # a point cloud or a path: nothing to collide with
        verts.append(v @ np.asarray(matrix)[:3, :3].T + np.asarray(matrix)[:3, 3])
        faces.append(f + offset)
        parts.append((str(name), first))
        offset += len(v)
        first += len(f)
    if not faces:
        empty = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        return *empty, nodes, tuple(markers), ()
    return np.concatenate(verts), np.concatenate(faces), nodes, tuple(markers), tuple(parts)
