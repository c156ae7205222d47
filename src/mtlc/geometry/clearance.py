"""Clearance of the manikin and its tools to the equipment, per frame and per goal.

For a compiled ``MotionIR`` and named meshes (vertices (V, 3) m in the scene's frame, faces
(F, 3)), ``frame_clearance`` places the body's 16 capsules (``mtlc.body.capsules.
collision_capsules``) and each held tool's capsule on every output frame and measures each
capsule's signed clearance to each mesh (``mtlc.geometry.distance``: negative is how deep the
capsule's surface is past the mesh's). ``goal_clearances`` reads that per goal: a TA segment
(the reach of a reach, move, turn or a tool's engage) is a goal; "path" is its frames, "site" the
frames of the TO segments on its track at the same site after it (the work there), or its last
frame when none follow; the parts are the goal's hand and forearm, and the tool it is made with.
A glove's thickness (``glove``, m) is taken off the hand's clearance (the capsules are bare).

Reads the IR, the body and the loads only: no pass (docs/collision.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from weakref import WeakKeyDictionary

import numpy as np
from numpy.typing import NDArray

from mtlc.body import forward
from mtlc.body.capsules import PartCapsule, capsule_segments, collision_capsules, tool_capsule
from mtlc.body.kinematics import Pose
from mtlc.geometry.distance import Mesh, MeshIndex
from mtlc.geometry.held import HeldPart
from mtlc.ir.model import MotionIR, Segment
from mtlc.loads import held_spans

FloatArray = NDArray[np.float64]

GLOVE_ALLOWANCE = 0.0  # m taken off the hand's clearance by default: bare hands
EPS = 1e-9  # s


@dataclass
class FrameClearance:
    """Signed clearance (m) of each capsule to each mesh on every output frame."""

    time: FloatArray  # (N,)
    capsules: tuple[str, ...]  # C names: the body's 16, then the held tools ("tool wrench_10mm")
    meshes: tuple[str, ...]  # M names, sorted
    clearance: FloatArray  # (N, C, M); NaN where a tool is not in the hand
    horizon: float | None = None  # clearances over it are lower bounds
    # the held parts (``model/node``, as their columns in ``meshes``) and how deep (m) each
    # goes into each mesh while a hand holds it: (N, H, M), NaN where no hand holds it and
    # against the held parts' own columns (``held_part_depths``)
    held: tuple[str, ...] = ()
    held_depth: FloatArray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    # (N, H, M) the triangle of the mesh each held part meets first (-1: none), to name the
    # node a finding is in (an index into that column's mesh)
    held_face: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 0, 0), np.int64))
    # (N, C, M) where a capsule touches a mesh and verify says it is no finding (a hand at its
    # goal's site, a hand on the part it holds; ``mtlc.passes.verify``): what the preview does
    # not paint as a clash. Empty until verify has judged.
    excused: NDArray[np.bool_] = field(default_factory=lambda: np.zeros((0, 0, 0), bool))


@dataclass
class PartClearance:
    """The smallest clearance of one part over a stretch of frames, and where it is."""

    part: str  # "right hand", "right forearm", "tool wrench_10mm"
    clearance: float  # m (after the glove allowance for a hand); inf: no mesh
    mesh: str | None  # the nearest mesh's name
    time: float  # s, the frame of the smallest clearance


@dataclass
class GoalClearance:
    """Clearance of a goal's hand, forearm and tool along its reach and at its site."""

    line: int  # the task line the goal came from
    effector: str
    site: str | None
    start: float
    end: float
    path: list[PartClearance] = field(default_factory=list)
    at_site: list[PartClearance] = field(default_factory=list)

    @property
    def smallest(self) -> PartClearance | None:
        """The tightest of all: the figure a report or a lint rule reads first."""
        parts = self.path + self.at_site
        return min(parts, key=lambda p: p.clearance) if parts else None


def carried_part_capsules(ir: MotionIR) -> list[tuple[PartCapsule, float, float]]:
    """Carried parts as (capsule, start, end): none yet. A load in the IR is a mass in a hand
    (``mtlc.loads.carried_loads``), with no size; when goals carry a part's geometry (a box in
    the hand's frame), it joins here as boxes' capsules or meshes, held over the load's window,
    and ``frame_clearance`` measures it with the tools."""
    del ir
    return []


def held_capsules(ir: MotionIR) -> list[tuple[PartCapsule, float, float]]:
    """Each held tool's capsule and the window it is in the hand; then the carried parts."""
    skel = ir.skeleton
    names = {s.name for s in skel.sites}
    out = [
        (tool_capsule(skel, site, tool), start, end)
        for site, tool, start, end in held_spans(ir)
        if site in names
    ]
    return out + carried_part_capsules(ir)


_INDICES: WeakKeyDictionary[Any, dict[str, MeshIndex]] = WeakKeyDictionary()


def scene_indices(models: Sequence[Any], library: str = "coal") -> dict[str, MeshIndex]:
    """Each scene model's (``SceneModel``) hierarchy by name, built once per model object and
    kept while it lives: verify, the preview and the tests ask about the same models."""
    out: dict[str, MeshIndex] = {}
    for model in models:
        if not len(model.faces):
            continue
        built = _INDICES.setdefault(model, {})
        if library not in built:
            built[library] = MeshIndex(model.vertices, model.faces, library=library)
        out[model.name] = built[library]
    return out


def scene_pieces(
    models: Sequence[Any], held: Sequence[HeldPart], library: str = "coal"
) -> tuple[dict[str, MeshIndex], dict[str, Any], list[tuple[HeldPart, MeshIndex]]]:
    """The scene's hierarchies with the held parts taken out of their models: each model's
    index by name (the rest of it where a part of it is held), each such rest's face indices
    into its model's faces by name (to name the node a finding is in), and each held part with
    its own index (in the model's frame; ``frame_clearance`` moves the queries, not the mesh).
    Built once per model object and part, as ``scene_indices``."""
    whole = scene_indices(models, library)
    faces_of: dict[str, Any] = {}
    pieces: list[tuple[HeldPart, MeshIndex]] = []
    by_name = {m.name: m for m in models}
    for name in sorted({p.model for p in held}):
        model = by_name[name]
        parts = [p for p in held if p.model == name]
        built = _INDICES.setdefault(model, {})
        taken = np.zeros(len(model.faces), dtype=bool)
        for part in parts:
            taken[part.faces] = True
            key = f"{library}/{part.column}"
            if key not in built:
                built[key] = MeshIndex(model.vertices, model.faces[part.faces], library=library)
            pieces.append((part, built[key]))
        rest = np.flatnonzero(~taken)
        key = f"{library}/{name}/rest:{','.join(sorted(p.column for p in parts))}"
        if key not in built:
            built[key] = MeshIndex(model.vertices, model.faces[rest], library=library)
        whole[name] = built[key]
        faces_of[name] = rest
    return whole, faces_of, pieces


def _into_part(a: FloatArray, placement: FloatArray) -> FloatArray:
    """(N, C, 3) points in a held part's own (rest) frame: its placement per frame undone."""
    rot, move = placement[:, :3, :3], placement[:, None, :3, 3]
    return np.einsum("nji,ncj->nci", rot, a - move)


def frame_clearance(
    ir: MotionIR,
    meshes: Mapping[str, Mesh] | Mapping[str, MeshIndex],
    library: str = "coal",
    horizon: float | None = 0.25,
    pose: Pose | None = None,
    through: bool = False,
    held: Sequence[tuple[HeldPart, MeshIndex]] = (),
) -> FrameClearance:
    """Every capsule's clearance to every mesh on the IR's output frames. ``horizon`` (m): a
    capsule farther than it from a mesh's bounding box gets a lower bound, not a query
    (``MeshIndex.segment_distance``); ``None`` asks every pair. ``pose``: the frames' forward
    kinematics when the caller has it already. ``through``: where a capsule's axis passes
    through a mesh's surface, its clearance is minus its radius and how far its nearer end
    sticks out beyond (``MeshIndex.through_depth``), not the radius alone. ``held``: parts the
    hands move (``scene_pieces``), measured where they are on each frame, each a column named
    ``model/node`` after the meshes'."""
    skel, frames = ir.skeleton, ir.frames
    assert skel is not None and frames is not None, "compile the IR first (frames, skeleton)"
    if pose is None:
        pose = forward(skel, frames.q, frames.root_position, frames.root_rotation, with_axes=False)
    body = collision_capsules(skel)
    tools = held_capsules(ir)
    caps = body + tuple(c for c, _, _ in tools)
    a, b, radii = capsule_segments(skel, pose, caps)
    indices = {
        name: m if isinstance(m, MeshIndex) else MeshIndex(*m, library=library)
        for name, m in sorted(meshes.items())
    }
    n, c = a.shape[0], a.shape[1]
    columns = [(index, a, b) for index in indices.values()]
    columns += [
        (index, _into_part(a, p.placement), _into_part(b, p.placement)) for p, index in held
    ]
    out = np.empty((n, c, len(columns)))
    for k, (index, ak, bk) in enumerate(columns):
        ak, bk = ak.reshape(-1, 3), bk.reshape(-1, 3)
        d = index.segment_distance(ak, bk, horizon)
        if through:
            touching = np.flatnonzero(d <= 0.0)
            d[touching] = -index.through_depth(ak[touching], bk[touching])
        out[:, :, k] = d.reshape(n, c) - radii[None, :]
    t = frames.time
    for j, (_, start, end) in enumerate(tools, start=len(body)):
        out[(t < start - EPS) | (t > end + EPS), j, :] = np.nan
    names = tuple(indices) + tuple(p.column for p, _ in held)
    depth, face = held_part_depths(t, held, indices, len(names))
    return FrameClearance(t, tuple(cap.name for cap in caps), names, out, horizon,
                          tuple(p.column for p, _ in held), depth, face)  # fmt: skip


def held_part_depths(
    t: FloatArray,
    held: Sequence[tuple[HeldPart, MeshIndex]],
    indices: Mapping[str, MeshIndex],
    columns: int,
) -> tuple[FloatArray, NDArray[np.int64]]:
    """(N, H, M) how deep each held part goes into each of ``indices`` (the scene's models,
    its own model's rest where it is taken from one) on the frames a hand holds it, and the
    triangle met (``MeshIndex.placed_depth``): the hand is excused against the part it holds,
    but the part is not excused against the rest of the equipment (a panel carried through
    the bay's wall). NaN where no hand holds it and against the held parts' columns (two
    parts carried into each other are not measured)."""
    depth = np.full((len(t), len(held), columns), np.nan)
    face = np.full((len(t), len(held), columns), -1, dtype=np.int64)
    for h, (part, index) in enumerate(held):
        holding = np.zeros(len(t), dtype=bool)
        for hold in part.holds:
            holding |= (t >= hold.start - EPS) & (t <= hold.end + EPS)
        rows = np.flatnonzero(holding)
        for k, other in enumerate(indices.values()):
            d, f = index.placed_depth(other, part.placement[rows])
            depth[rows, h, k], face[rows, h, k] = d, f
    return depth, face


def goal_groups(ir: MotionIR) -> list[tuple[Segment, list[Segment]]]:
    """Each TA segment with the TO segments after it on its track, at its site, before the
    track's next TA."""
    groups: list[tuple[Segment, list[Segment]]] = []
    by_track: dict[str, list[Segment]] = {}
    for seg in sorted(ir.segments, key=lambda s: (s.start, s.end)):
        if seg.kind in ("TA", "TO"):
            by_track.setdefault(seg.track, []).append(seg)
    for segs in by_track.values():
        for i, seg in enumerate(segs):
            if seg.kind != "TA":
                continue
            work = []
            for nxt in segs[i + 1 :]:
                if nxt.kind == "TA":
                    break
                if nxt.goal.site == seg.goal.site:
                    work.append(nxt)
            groups.append((seg, work))
    return sorted(groups, key=lambda g: (g[0].start, g[0].track))


def _parts(seg: Segment, capsules: tuple[str, ...]) -> list[str]:
    """The goal's hand and forearm, and its tool when it has one held."""
    word = "right" if seg.goal.effector.startswith("r") else "left"
    parts = [f"{word} hand", f"{word} forearm"]
    tool = seg.goal.params.get("tool")
    if isinstance(tool, dict) and f"tool {tool.get('name')}" in capsules:
        parts.append(f"tool {tool.get('name')}")
    return parts


def _smallest(
    fc: FrameClearance, part: str, mask: NDArray[np.bool_], glove: float
) -> PartClearance:
    j = fc.capsules.index(part)
    values = fc.clearance[mask, j, :] - (glove if part.endswith("hand") else 0.0)
    if values.size == 0 or np.all(np.isnan(values)):
        return PartClearance(part, float("inf"), None, float("nan"))
    flat = int(np.nanargmin(values))
    row, col = divmod(flat, values.shape[1])
    return PartClearance(
        part, float(values[row, col]), fc.meshes[col], float(fc.time[np.flatnonzero(mask)[row]])
    )


def goal_clearances(
    ir: MotionIR, fc: FrameClearance, glove: float = GLOVE_ALLOWANCE
) -> list[GoalClearance]:
    """The smallest clearance of each goal's hand, forearm and tool along its reach and at its
    site (see the module docstring), a glove's thickness ``glove`` (m) off the hand's."""
    t = fc.time
    out = []
    for ta, work in goal_groups(ir):
        path = (t >= ta.start - EPS) & (t <= ta.end + EPS)
        site = np.zeros_like(path)
        for seg in work:
            site |= (t >= seg.start - EPS) & (t <= seg.end + EPS)
        if not site.any():
            site[int(np.argmin(np.abs(t - ta.end)))] = True
        parts = _parts(ta, fc.capsules)
        out.append(
            GoalClearance(
                line=ta.provenance.origin.line,
                effector=ta.goal.effector,
                site=ta.goal.site,
                start=ta.start,
                end=max([ta.end, *(s.end for s in work)]),
                path=[_smallest(fc, p, path, glove) for p in parts],
                at_site=[_smallest(fc, p, site, glove) for p in parts],
            )
        )
    return out


__all__ = [
    "GLOVE_ALLOWANCE",
    "FrameClearance",
    "GoalClearance",
    "PartClearance",
    "carried_part_capsules",
    "frame_clearance",
    "goal_clearances",
    "held_part_depths",
    "scene_indices",
]
