"""Parts of a scene model that a hand grasps and moves: where they are on every output frame.

A model is placed once, but a part the hands take out (the fuel filter's bowl, the access
panel) goes where the hands go, and a collision check against the model where it was is false:
the hands carrying the panel read as "through the panel". The rule (docs/collision.md, "Held
parts"):

* A **grasp** is a closing grip of a bare hand (its goal before the grip has the hand, not a
  tool, as effector: a hand closing on a wrench at a bolt holds the wrench) whose goal's site is
  a named node of a model: a node of that name (`sites from m`), else one within
  ``NODE_MATCH`` of the goal's position (`site s = m.node`).
* The **part** it holds is that model's glTF part (``SceneModel.parts``) nearest the node, if
  it is within ``GRASP_REACH``; a model of one part (a one-part file or a solid) is held whole.
  Nothing else of the model moves with it (the bolt heads of the panel stay: the language does
  not say they came out with it).
* It is **held** from the grip's start to the end of that hand's next opening grip (or the end
  of the motion), if at the grip's start the hand's grip point is within ``GRASP_REACH`` of its
  goal's position carried to where the part is then (a part taken away earlier is not grasped
  again at its old place).
* It **moves** with the hand while held: its grasped point stays at the hand's grip point.
  Until the grip point is more than ``TAKEN_OUT`` from where it closed, the part only slides
  with it, unturned: a bowl turned off its thread turns about the thread's axis, not with the
  wrist (a wrist turn is not a rotation of the part; a round part turned about its own axis is
  where it was). From then on it is rigid in the hand's frame (the hand joint's rotation at the
  grip point), turning as the hand turns. With two hands on it, it goes with
  the one that closed first (the right on a tie), then with the other when that one lets go.
  Released, it stays where it was let go.

Reads the IR, the body and the models only: no pass.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from mtlc.body import site_positions
from mtlc.body.kinematics import Pose
from mtlc.geometry.distance import point_triangle_distance
from mtlc.geometry.model import SceneModel
from mtlc.ir.model import MotionIR, Segment

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

NODE_MATCH = 1e-3  # m: a goal's site this close to a model's node is that node
GRASP_REACH = 0.10  # m: a closed hand holds a part this near its node (a hand's length)
# m: a held part slides with the grip point, unturned, until the hand has moved this far from
# where it closed, then turns with the hand: a turn in place turns it about its own thread,
# not about the wrist's axis
TAKEN_OUT = 0.05
SIDES = ("r", "l")
EPS = 1e-9  # s


@dataclass(frozen=True, eq=False)
class Hold:
    """One hand on a part: from the grip's start to the end of its release."""

    side: str  # "r" or "l"
    start: float  # s
    end: float  # s
    goal: Segment  # the goal that brought the hand to the node (its line, its start)
    at: FloatArray  # where that goal put the hand (a two-handed grasp's hands either side)


@dataclass
class HeldPart:
    """A model's part that a hand grasps, with its placement on every output frame."""

    model: str  # the SceneModel's name
    node: str | None  # its glTF part's name; None: the whole model
    marker: str  # the node the hand grasps it at
    faces: IntArray  # (F,) indices into the model's faces that move
    holds: list[Hold] = field(default_factory=list)
    # (N, 4, 4) its placement on each output frame, from where the model puts it
    placement: FloatArray = field(default_factory=lambda: np.zeros((0, 4, 4)))

    @property
    def column(self) -> str:
        """Its name among the meshes measured: ``model/node`` (``model/`` when whole)."""
        return f"{self.model}/{self.node or ''}"


def _part_faces(model: SceneModel, index: int) -> IntArray:
    """The face indices of the model's ``index``-th glTF part."""
    first = model.parts[index][1]
    last = model.parts[index + 1][1] if index + 1 < len(model.parts) else len(model.faces)
    return np.arange(first, last, dtype=np.int64)


def part_at_node(model: SceneModel, marker: str) -> tuple[str | None, IntArray] | None:
    """The part a hand closing at ``marker`` holds: the nearest glTF part within
    ``GRASP_REACH`` (its name and faces), the whole model when it has no parts, None when
    nothing is that near."""
    point = model.nodes[marker][0]
    tri = model.vertices[model.faces]
    dist = point_triangle_distance(point[None, :], tri) if len(tri) else np.zeros(0)
    if not dist.size or dist.min() > GRASP_REACH:
        return None
    if not model.parts:
        return None, np.arange(len(model.faces), dtype=np.int64)
    face = int(np.argmin(dist))
    firsts = [first for _, first in model.parts]
    k = int(np.searchsorted(firsts, face, side="right")) - 1
    if k < 0:
        return None
    return model.parts[k][0], _part_faces(model, k)


def _node_at(
    models: Sequence[SceneModel], site: str | None, position: FloatArray
) -> tuple[SceneModel, str] | None:
    """The model node a goal is at: the one named as its site (`sites from m`), else one at its
    position (`site s = m.node`); the first by model, then node name."""
    for model in models:
        if site in model.nodes:
            return model, site
    for model in models:
        for name in sorted(model.nodes):
            if np.linalg.norm(model.nodes[name][0] - position) <= NODE_MATCH:
                return model, name
    return None


def _grasps(ir: MotionIR, side: str) -> list[tuple[Segment, Segment, float]]:
    """(closing grip, the goal before it, end of the release after it) of one bare hand."""
    hand = f"{side}_hand"
    grips = sorted((s for s in ir.on_track(hand) if s.kind == "grip"), key=lambda s: s.start)
    goals = sorted(
        (s for s in ir.on_track(f"{side}_arm")
         if s.kind in ("TA", "TO") and s.goal.position is not None),
        key=lambda s: s.end,
    )  # fmt: skip
    end_of_motion = max((s.end for s in ir.segments), default=0.0)
    out = []
    for k, grip in enumerate(grips):
        if grip.goal.params.get("state") != "closed":
            continue
        before = [g for g in goals if g.end <= grip.start + EPS]
        if not before or before[-1].goal.effector != hand:
            continue
        release = next((g for g in grips[k + 1 :] if g.goal.params.get("state") != "closed"), None)
        out.append((grip, before[-1], release.end if release is not None else end_of_motion))
    return out


def _hand_frames(ir: MotionIR, pose: Pose, side: str) -> FloatArray:
    """(N, 4, 4) the hand's frame on each output frame: its joint's rotation at its grip point."""
    skel = ir.skeleton
    assert skel is not None
    name = f"{side}_hand"
    out = np.zeros((*pose.p.shape[:-2], 4, 4))
    out[..., :3, :3] = pose.R[..., skel.joint_index(skel.site(name).joint), :, :]
    out[..., :3, 3] = site_positions(skel, pose, name)
    out[..., 3, 3] = 1.0
    return out


def held_parts(ir: MotionIR, models: Sequence[SceneModel], pose: Pose) -> list[HeldPart]:
    """Every model part a hand grasps (the module's rule), with its placement per output frame;
    none for a scene without named nodes."""
    frames = ir.frames
    assert frames is not None
    with_nodes = [m for m in models if m.nodes and len(m.faces)]
    if not with_nodes:
        return []
    found: dict[tuple[str, str | None], HeldPart] = {}
    for side in SIDES:
        for grip, goal, end in _grasps(ir, side):
            position = np.asarray(goal.goal.position, dtype=float).reshape(-1, 3)[0]
            at = _node_at(with_nodes, goal.goal.site, position)
            if at is None:
                continue
            model, marker = at
            part = part_at_node(model, marker)
            if part is None:
                continue
            node, faces = part
            held = found.setdefault((model.name, node), HeldPart(model.name, node, marker, faces))
            held.holds.append(Hold(side, grip.start, end, goal, position))
    t = frames.time
    hands = {side: _hand_frames(ir, pose, side) for side in SIDES}
    out = []
    for (name, _), part in sorted(found.items(), key=lambda kv: (kv[0][0], kv[0][1] or "")):
        model = next(m for m in with_nodes if m.name == name)
        part.holds.sort(key=lambda h: (h.start, SIDES.index(h.side)))
        part.placement, part.holds = _placements(t, hands, part.holds)
        out.append(part)
    return out


def _placements(
    t: FloatArray, hands: dict[str, FloatArray], holds: list[Hold]
) -> tuple[FloatArray, list[Hold]]:
    """(N, 4, 4) a part's placement per frame under ``holds``, and the holds kept: one whose
    hand is not within ``GRASP_REACH`` of its goal's place on the part (where the part is
    then) at its start holds nothing."""
    n = len(t)
    placement = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    kept: list[Hold] = []
    decided: set[int] = set()
    carrier: Hold | None = None
    closed_at = np.zeros(3)  # the carrying hand's grip point where it took the part
    mounted = np.eye(4)  # the part's placement then
    anchor: FloatArray | None = None  # the part in the carrying hand's frame, once it moves it
    for i in range(n):
        if i:
            placement[i] = placement[i - 1]
        for hold in holds:
            if id(hold) in decided or not (hold.start - EPS <= t[i] <= hold.end + EPS):
                continue
            decided.add(id(hold))
            there = placement[i, :3, :3] @ hold.at + placement[i, :3, 3]
            if np.linalg.norm(hands[hold.side][i, :3, 3] - there) <= GRASP_REACH:
                kept.append(hold)
        active = [h for h in kept if h.start - EPS <= t[i] <= h.end + EPS]
        now = active[0] if active else None
        if now is not carrier:
            carrier, anchor = now, None
            if carrier is not None:
                closed_at = hands[carrier.side][i, :3, 3].copy()
                mounted = placement[i].copy()
        if carrier is None:
            continue
        frame = hands[carrier.side][i]
        if anchor is None:  # not taken out yet: it slides with the grip point, unturned
            placement[i] = mounted
            placement[i, :3, 3] += frame[:3, 3] - closed_at
            if np.linalg.norm(frame[:3, 3] - closed_at) > TAKEN_OUT:
                anchor = np.linalg.inv(frame) @ placement[i]
        else:
            placement[i] = frame @ anchor
    return placement, kept
