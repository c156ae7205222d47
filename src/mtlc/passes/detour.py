"""A reach's way to its approach point planned around the equipment (issue 20), before pace.

The approach solver keys a reach by its start pose and the approach pose (and maybe a middle
key that lifts it over the floor or out of the body); the joint-space path between them knows
nothing of the scene's models, and the hand, forearm or held tool swept through the access
panel or the fuel filter bay's wall on the way. Bending the dense frames after ``pace`` (the
i-path20 branch) had to squeeze the detour into the reach's own time: the hand's speed got a
second peak and the reach's LDLJ fell.

Here the way is chosen while it is still a path of keys, before ``pace`` times it. For each
arm's reach (a group of TA segments, ``approach.groups``, sharing one window), the path the
keys make (PCHIP, as ``interpolate``) is sampled at ``SAMPLES`` poses, smoothed as ``pace``
will smooth it (``PACE_SIGMA``), and its hand, forearm and held tool measured against the
models (``Obstacles``: each capsule's radius less its axis's distance, and where the axis
crosses a surface how far its nearer end sticks out beyond, as verify measures; a grasped
part where it lies while no hand holds it, ``PlacedPart``). A reach that starts or ends in a
model (``END_INSIDE``) is left: the pose at the site holds that finding. Elsewhere:

* **The bow.** For each direction (the six axes, the goal sites' normals, back toward the
  shoulder), the least rigid move of the arm's capsules (``MOVES``) that takes each inside
  sample ``MARGIN`` out, and the peak and height of one minimum-jerk bell of offset
  (``bump``) that gives every inside sample its move with the least height (``best_peak``).
  The path's poses at the reach's keys, the peak and ``BUMP_KEYS`` of the way to and from it
  are solved so the hand and the elbow move by the bell's offset there (shoulder and elbow
  flexion; the forearm's twist and the wrist as the path has them) and become its keys.
* **Kept when.** ``SCALES`` of the height, for the ``TRIED`` least directions, until the
  smoothed path is ``MARGIN`` clear; the least deep kept if ``GAIN`` less deep, no arm goes
  deeper into the trunk or thighs, the hand's path is at most ``MAX_LONGER`` times as long,
  and the hand's paced path keeps its smoothness (``paced_ldlj``: ``LDLJ_FLOOR``,
  ``LDLJ_LOSS``). Up to ``VIA_KEYS`` bows, each where the last left the path in.
* **A free arm** that the reach's trunk turn carries through a model on the way (clear at
  the reach's start and end) bows away by the same kind of bell, keyed with the reach's
  trunk carrier (``free_arm_out``).

``pace`` then times the longer path as one minimum-jerk bell: the detour is part of the path,
not a second movement on top of it. Not done: a reach that starts or ends in a model, the
contact (TO) phase, a free arm in a model at a reach's start or end (the clearance pass knows
the body, not the models), a held part as an obstacle while it is held.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.body.capsules import (
    PartCapsule,
    capsule_segments,
    collision_capsules,
    limbs_of_sides,
    self_intersection,
)
from mtlc.body.ik import Goal, default_dofs, prepare, solve_ta
from mtlc.body.kinematics import Pose
from mtlc.body.skeleton import Site, Skeleton
from mtlc.geometry.clearance import held_capsules, scene_pieces
from mtlc.geometry.distance import MeshIndex
from mtlc.geometry.held import (
    SIDES,
    HeldPart,
    Hold,
    _grasps,
    _node_at,
    _placements,
    part_at_node,
)
from mtlc.geometry.held import _hand_frames as hand_frames
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment
from mtlc.passes.approach import groups
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import track
from mtlc.passes.profile import JOINT_WEIGHT, bell_ldlj, minimum_jerk, smooth_path
from mtlc.passes.state import TRUNK_DOFS, PoseState

PART_FPS = 30.0  # a grasped part's placement is followed on this clock (frames a second)
SAMPLES = 25  # poses of a reach's path measured against the models, ends included
# of the reach's samples: ``pace`` smooths a movement's path by up to a Gaussian of 0.25 of
# its progress (``pace.SMOOTH_SIGMAS``), the approach and the contact together; the approach
# is most of it
PACE_SIGMA = 0.3
MARGIN = 0.01  # m the arm's surface is to be kept out of a model on the way
GAIN = 0.003  # m a via key must take off the path's depth to be kept
MOVES = (0.01, 0.02, 0.04, 0.07, 0.1, 0.14, 0.2)  # m: the rigid moves tried, least first
VIA_KEYS = 2  # detours added to one reach at most (the second where the first left it in)
# shares of the way from the reach's start to a detour's peak, and from the peak to its end,
# that get a key (with the peak: PCHIP through them follows the bell)
BUMP_KEYS = np.array([1.0 / 3.0, 2.0 / 3.0])
TRIED = 3  # directions tried, the least height first
SCALES = (1.0, 1.5, 2.0)  # the via key's offset as multiples of the rigid move, least first
MAX_LONGER = 2.0  # a via key may make the hand's path at most this many times as long
# m: a reach whose start or end pose is deeper than this in a model keeps its way (the hand
# at a site, its fingers through the surface it works on: verify's finding stays whatever
# the way between, and bowing it cost the CAD examples' reaches their smoothness: LDLJ
# under -8 10 -> 42 of 2 226 with every such reach bowed)
END_INSIDE = 0.005
END_SHARE = 0.25  # of the reach's window: an end pose's depth is excused fading over it
VIA_OFF_END = 0.1  # of the reach's window: a via key is kept this far off its ends
HORIZON = 0.1  # m: a capsule this far from a model's box is not asked
LDLJ_POINTS = 31  # the paced path's samples for ``paced_ldlj``: the bench's 30 a second over a
# reach's second (finer, the 25-sample path's PCHIP knots read as jerk: a straight reach -8.5)
# a detour may make the hand's paced path less smooth (LDLJ) down to the bench's floor for
# every reach (bench/motion.py: >= -8), or by this much where it was below it already
LDLJ_FLOOR = -8.0
LDLJ_LOSS = 0.5
BODY_SLACK = 1e-3  # m a via key may take a forearm or hand deeper into the trunk or thighs
TWIST_AND_WRIST = ("_pro", "_wrist_flex", "_wrist_dev")  # dofs the via solve leaves alone
ELBOW_SITE = "{side}_elbow_point"  # a site at the elbow joint, for the via solve
HOMOTOPY = 3  # steps the via solve takes the offset in
WORDS = {"r": "right", "l": "left"}
ARM_TRACKS = ("r_arm", "l_arm")
TRUNK_TURN = 0.02  # rad a reach's keys must turn a trunk dof by to carry a free arm
EPS = 1e-9


@dataclass
class Obstacles:
    """The models a reach must stay out of: each model without the parts hands grasp, and each
    grasped part where it is while no hand holds it (where the model has it until its first
    grasp, where a hand set it down after; ``PlacedPart``)."""

    fixed: list[MeshIndex]
    parts: list[PlacedPart]

    def depth(self, a: FloatArray, b: FloatArray, radii: FloatArray, t: FloatArray) -> FloatArray:
        """(K,) the deepest capsule (axes ``a``-``b`` (K, C, 3), radii (C,)) of each pose at
        times ``t`` (K,) into any model (m, positive inside)."""
        out = np.full(a.shape[:2], -np.inf)
        for index in self.fixed:
            out = np.maximum(out, capsule_depths(index, a, b, radii))
        for part in self.parts:
            k = np.clip(np.searchsorted(part.times, t + EPS) - 1, 0, len(part.times) - 1)
            rows = np.flatnonzero(~part.held[k])
            if not rows.size:
                continue
            place = part.placement[k[rows]]
            rot, move = place[:, :3, :3], place[:, None, :3, 3]
            la = np.einsum("nji,ncj->nci", rot, a[rows] - move)
            lb = np.einsum("nji,ncj->nci", rot, b[rows] - move)
            out[rows] = np.maximum(out[rows], capsule_depths(part.index, la, lb, radii))
        return out.max(axis=1)


@dataclass
class PlacedPart:
    """A grasped part's mesh (in its model's frame) and where it is over the motion, on a
    coarse clock (``PART_FPS``) from the keyframes: its placement and whether a hand holds it
    then (held, it moves with the hand and is not in the reach's way)."""

    index: MeshIndex
    times: FloatArray  # (G,)
    placement: FloatArray  # (G, 4, 4)
    held: np.ndarray  # (G,) bool


def capsule_depths(index: MeshIndex, a: FloatArray, b: FloatArray, radii: FloatArray) -> FloatArray:
    """(K, C) each capsule's depth into one mesh: its radius less its axis's distance, and
    where the axis crosses a surface how far its nearer end sticks out (verify's rule)."""
    flat_a, flat_b = a.reshape(-1, 3), b.reshape(-1, 3)
    d = index.segment_distance(flat_a, flat_b, HORIZON)
    touching = np.flatnonzero(d <= 0.0)
    if touching.size:
        d[touching] = -index.through_depth(flat_a[touching], flat_b[touching])
    return radii[None, :] - d.reshape(a.shape[:2])


def grasped_parts(ir: MotionIR, models: list) -> list[HeldPart]:
    """The model parts a hand grasps (``geometry.held``'s rule), without their placements:
    what is known before the frames exist."""
    with_nodes = [m for m in models if m.nodes and len(m.faces)]
    found: dict[tuple[str, str | None], HeldPart] = {}
    for side in SIDES:
        for grip, goal, end in _grasps(ir, side):
            position = np.asarray(goal.goal.position, dtype=float).reshape(-1, 3)[0]
            at = _node_at(with_nodes, goal.goal.site, position)
            part = part_at_node(at[0], at[1]) if at is not None else None
            if at is None or part is None:
                continue
            held = found.setdefault(
                (at[0].name, part[0]), HeldPart(at[0].name, part[0], at[1], part[1])
            )
            held.holds.append(Hold(side, grip.start, end, goal, position))
    return [found[k] for k in sorted(found, key=lambda k: (k[0], k[1] or ""))]


def obstacles_of(ir: MotionIR, state: PoseState) -> Obstacles | None:
    """The scene's models as ``Obstacles``; None without models. A grasped part's placement
    follows ``geometry.held``'s rule on the body as keyed so far (each dof at its last key:
    where a hand grasps and where it lets go are keys)."""
    models = [m for m in ir.geometry if len(m.faces)]
    if not models:
        return None
    parts = grasped_parts(ir, models)
    fixed, _, pieces = scene_pieces(models, parts)
    placed = []
    if pieces:
        end = max(s.end for s in ir.segments)
        bounds = [t for part, _ in pieces for h in part.holds for t in (h.start, h.end)]
        times = np.unique(np.concatenate([np.arange(0.0, end, 1.0 / PART_FPS), bounds]))
        q = state.q_at_many(times)
        root = state.root_at_many(times)
        pose = forward(ir.skeleton, q, *root, with_axes=False)
        hands = {side: hand_frames(ir, pose, side) for side in SIDES}
        for part, index in pieces:
            placement, kept = _placements(times, hands, part.holds)
            held = np.zeros(len(times), dtype=bool)
            for h in kept:
                held |= (times >= h.start - EPS) & (times <= h.end + EPS)
            placed.append(PlacedPart(index, times, placement, held))
    return Obstacles(list(fixed.values()), placed)


class ArmCapsules:
    """The reaching arms' hand and forearm capsules and the tools their hands hold."""

    def __init__(self, ir: MotionIR, sides: list[str], t0: float, t1: float) -> None:
        skel = ir.skeleton
        names = {f"{WORDS[s]} {part}" for s in sides for part in ("hand", "forearm")}
        caps = [c for c in collision_capsules(skel) if c.name in names]
        caps += [
            c for c, start, end in held_capsules(ir)
            if c.start[0][:2] in {f"{s}_" for s in sides} and start < t1 and end > t0
        ]  # fmt: skip
        self.skel = skel
        self.caps: tuple[PartCapsule, ...] = tuple(caps)
        self.radii = np.array([c.radius for c in caps])

    def depth(self, obstacles: Obstacles, pose: Pose, t: FloatArray) -> FloatArray:
        """(K,) the deepest capsule of each pose into the models."""
        a, b, _ = capsule_segments(self.skel, pose, self.caps)
        return obstacles.depth(a, b, self.radii, t)


@dataclass
class Reach:
    """A group of TA segments keyed over one window, and the body around their path."""

    skel: Skeleton
    segs: list[Segment]
    sides: list[str]
    t0: float
    t1: float
    base: FloatArray  # (K, D) the body at the samples' times, before the reach's keys
    root: tuple[FloatArray, FloatArray]  # (K, 3), (K, 4) at the samples' times
    times: FloatArray  # (K,)

    def path(self, keys: list[Keyframes], smooth: bool = True) -> FloatArray:
        """(K, D) the body along the path ``keys`` (one per segment) make (PCHIP, as
        ``interpolate``) at the samples' times; with ``smooth`` as ``pace`` will smooth it
        (a Gaussian of ``PACE_SIGMA`` of the reach: it flattens a detour's bump, and the
        depth that counts is the smoothed path's)."""
        q = self.base.copy()
        for kf in keys:
            idx = [self.skel.dof_index(n) for n in kf.dofs]
            q[:, idx] = track(kf.time, kf.q, self.times)
        return smooth_path(q, PACE_SIGMA * (len(q) - 1)) if smooth else q


def reach_of(ir: MotionIR, state: PoseState, segs: list[Segment]) -> Reach | None:
    """The group ``segs`` as a ``Reach``, or None if its segments do not share one window (a
    via key at one time for all) or one is not keyed."""
    if any(s.keyframes is None or len(s.keyframes.time) < 2 for s in segs):
        return None
    t0, t1 = segs[0].start, segs[0].end
    if any(abs(s.start - t0) > EPS or abs(s.end - t1) > EPS for s in segs) or t1 - t0 <= EPS:
        return None
    sides = sorted({s.track[0] for s in segs})
    times = np.linspace(t0, t1, SAMPLES)
    base = state.q_at_many(times, skip=segs)
    root = state.root_at_many(times, skip=segs)
    return Reach(ir.skeleton, segs, sides, t0, t1, base, root, times)


def directions(normals: list[FloatArray], shoulder: FloatArray, hand: FloatArray):
    """Unit directions a via key may move the arm along: the six axes, the goal sites'
    normals, back toward the shoulder."""
    out = [np.eye(3)[k] * s for k in range(3) for s in (1.0, -1.0)]
    out += [*normals, shoulder - hand]
    unit = [d / np.linalg.norm(d) for d in out if np.linalg.norm(d) > 1e-9]
    return [d for k, d in enumerate(unit) if all(np.abs(d - e).max() > 1e-6 for e in unit[:k])]


def least_moves(
    arms: ArmCapsules, obstacles: Obstacles, pose: Pose, t: FloatArray, direction: FloatArray
) -> FloatArray:
    """(K,) per pose of ``pose`` (at times ``t``) the least of ``MOVES`` that takes the arm's
    capsules ``MARGIN`` out when moved rigidly along ``direction``; inf where none does."""
    a, b, _ = capsule_segments(arms.skel, pose, arms.caps)
    out = np.full(len(t), np.inf)
    todo = np.arange(len(t))
    for move in MOVES:
        if not todo.size:
            break
        shift = move * direction
        clear = obstacles.depth(a[todo] + shift, b[todo] + shift, arms.radii, t[todo]) <= -MARGIN
        out[todo[clear]] = move
        todo = todo[~clear]
    return out


def best_peak(
    moves: FloatArray, share: FloatArray, inside: np.ndarray, peaks: np.ndarray
) -> tuple[int, float]:
    """Of the samples ``peaks``, the one a ``bump`` peaking there needs the least height to
    give each sample ``inside`` its move ``moves``, and that height (``share``: each sample's
    share of the reach)."""
    best = (int(peaks[0]), np.inf)
    for p in peaks:
        lift = bump(share[inside], float(share[p]))
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.where(moves > 0.0, moves / lift, 0.0)
        height = float(np.nanmax(need)) if len(need) else 0.0
        if height < best[1]:
            best = (int(p), height)
    return best


_WITH_ELBOWS: dict[int, Skeleton] = {}


def with_elbows(skel: Skeleton) -> Skeleton:
    """The skeleton with a site at each elbow joint, for the via solve to carry the forearm
    with the hand; kept per skeleton object."""
    found = _WITH_ELBOWS.get(id(skel))
    if found is None or found.joints is not skel.joints:
        extra = tuple(
            Site(ELBOW_SITE.format(side=side), f"{side}_elbow", (0.0, 0.0, 0.0), "landmark")
            for side in ("r", "l")
        )
        found = _WITH_ELBOWS[id(skel)] = replace(skel, sites=skel.sites + extra)
    return found


def carrying_dofs(skel: Skeleton, side: str) -> list[int]:
    """The shoulder's and the elbow's flexion: the forearm's twist and the wrist stay as the
    path has them (a palm-only goal moves the palm by flicking the wrist)."""
    arm = default_dofs(skel, [f"{side}_hand"], "arm")
    return [d for d in arm if not skel.dof_names[d].endswith(TWIST_AND_WRIST)]


def solve_via(
    skel: Skeleton,
    q: FloatArray,
    root: tuple[FloatArray, FloatArray],
    sides: list[str],
    offset: FloatArray,
) -> FloatArray:
    """Poses ``q`` (K, D) with each side's shoulder and elbow solved so that its hand and
    elbow move by ``offset`` (K, 3) as well as they can (the forearm carried along as the
    rigid move assumed), in ``HOMOTOPY`` steps (one long step can land the arm on another
    branch between two neighbouring keys)."""
    skel = with_elbows(skel)
    pose = forward(skel, q, *root, with_axes=False)
    points = {side: [f"{side}_hand", ELBOW_SITE.format(side=side)] for side in sides}
    start = {n: site_positions(skel, pose, n) for side in sides for n in points[side]}
    out = q.copy()
    for side in sides:
        model = prepare(skel, points[side], out, dofs=carrying_dofs(skel, side),
                        root_position=root[0], root_rotation=root[1])  # fmt: skip
        for share in np.linspace(0.0, 1.0, HOMOTOPY + 1)[1:]:
            goals = [Goal(n, position=start[n] + share * offset) for n in points[side]]
            out = solve_ta(skel, goals, out, model=model, restarts=0, null_gain=0.0,
                           tol=5e-4).q  # fmt: skip
    return skel.clip(out)


def bump(share: FloatArray, peak: float) -> FloatArray:
    """(K,) the detour's profile at shares of the reach: 0 at its ends, 1 at ``peak``, each
    side one minimum-jerk rise (no speed at the ends or the top: one smooth bell of offset,
    which ``pace`` then times with the rest of the path)."""
    up = np.clip(share / max(peak, EPS), 0.0, 1.0)
    down = np.clip((1.0 - share) / max(1.0 - peak, EPS), 0.0, 1.0)
    return np.where(share <= peak, minimum_jerk(up), minimum_jerk(down))


def key_rows(reach: Reach, seg: Segment, peak: int) -> np.ndarray:
    """The samples a detour peaking at sample ``peak`` keys ``seg`` at: the nearest to its
    own keys, the peak, and ``BUMP_KEYS`` shares of the way to the peak and from it."""
    n = len(reach.times) - 1
    own = (np.asarray(seg.keyframes.time, dtype=float) - reach.t0) / (reach.t1 - reach.t0)
    at = peak / n
    wanted = np.concatenate([own, BUMP_KEYS * at, at + BUMP_KEYS * (1.0 - at), [at, 0.0, 1.0]])
    return np.unique(np.clip(np.rint(wanted * n), 0, n).astype(int))


def bumped_keys(reach: Reach, peak: int, offset: FloatArray) -> list[Keyframes]:
    """The reach's keys with its path bowed by ``offset`` (3,) times ``bump`` peaking at
    sample ``peak``: keys at the samples nearest the reach's own keys and at ``BUMP_KEYS``
    shares of the way to the peak and from it, each the path's pose there with the arms
    solved to move by its share of the offset (``solve_via``)."""
    skel = reach.skel
    share = (reach.times - reach.t0) / (reach.t1 - reach.t0)
    rows = np.unique(np.concatenate([key_rows(reach, s, peak) for s in reach.segs]))
    at = peak / (len(reach.times) - 1)
    q = reach.path([s.keyframes for s in reach.segs], smooth=False)[rows]
    lift = bump(share[rows], at)
    moved = np.flatnonzero(lift > 1e-6)
    root = (reach.root[0][rows[moved]], reach.root[1][rows[moved]])
    q[moved] = solve_via(skel, q[moved], root, reach.sides, lift[moved, None] * offset[None, :])
    out = []
    for seg in reach.segs:
        kf = seg.keyframes
        idx = [skel.dof_index(name) for name in kf.dofs]
        out.append(Keyframes(time=reach.times[rows], dofs=kf.dofs, q=q[:, idx]))
    return out


def hand_length(skel: Skeleton, pose: Pose, sides: list[str]) -> float:
    """The hands' path length (m) over the poses, the longer hand's."""
    lengths = [
        float(np.linalg.norm(np.diff(site_positions(skel, pose, f"{s}_hand"), axis=0), axis=-1)
              .sum())
        for s in sides
    ]  # fmt: skip
    return max(lengths)


def paced_ldlj(skel: Skeleton, q: FloatArray, pose: Pose, sides: list[str]) -> float:
    """The hands' log dimensionless jerk (docs/metrics.md's reach figure) along the sampled
    path ``q`` (K, D) with ``pose`` when ``pace`` times it: progress (the hands' arc length
    plus ``profile.JOINT_WEIGHT`` times the joints' path) along one minimum-jerk bell. The
    worse hand's; a detour must not turn a smooth reach into a rough one."""
    step = np.linalg.norm(np.diff(q, axis=0), axis=1) * JOINT_WEIGHT
    hands = [site_positions(skel, pose, f"{s}_hand") for s in sides]
    for p in hands:
        step = step + np.linalg.norm(np.diff(p, axis=0), axis=1)
    u = np.concatenate([[0.0], np.cumsum(step)])
    if u[-1] <= 1e-9:
        return 0.0
    u = u / u[-1] + np.arange(len(u)) * 1e-9
    return bell_ldlj(hands, u, LDLJ_POINTS)


def body_depth(skel: Skeleton, pose: Pose, sides: list[str]) -> float:
    """How deep the arms' forearms and hands go into the trunk and thighs along the path."""
    return float(self_intersection(skel, pose, limbs_of_sides(sides))[0].max())


def end_allowance(depth: FloatArray, share: FloatArray) -> FloatArray:
    """(K,) how deep the path may be at each sample because an end pose is (the hand at a
    site, its fingers through the surface it works on, or an approach pose inside: no path
    between them changes that): each end's depth, fading to nothing over ``END_SHARE`` of
    the window."""
    first, last = max(float(depth[0]), 0.0), max(float(depth[-1]), 0.0)
    fade_in = np.clip(1.0 - share / END_SHARE, 0.0, 1.0)
    fade_out = np.clip(1.0 - (1.0 - share) / END_SHARE, 0.0, 1.0)
    return np.maximum(first * fade_in, last * fade_out)


def plan(ir: MotionIR, reach: Reach, obstacles: Obstacles) -> None:
    """Add via keys to the reach while its path goes into a model and one more takes it
    less deep (``VIA_KEYS`` at most; the module docstring); then keep a free arm the reach's
    trunk carries out of the models (``free_arm_out``)."""
    arms = ArmCapsules(ir, reach.sides, reach.t0, reach.t1)
    for _ in range(VIA_KEYS):
        if not add_via(ir, reach, obstacles, arms):
            break
    for side in SIDES:
        if side not in reach.sides:
            free_arm_out(ir, reach, obstacles, side)


def trunk_carrier(reach: Reach) -> Segment | None:
    """The reach's segment whose keys turn the trunk (lumbar, thorax), if one does."""
    for seg in reach.segs:
        kf = seg.keyframes
        cols = [k for k, name in enumerate(kf.dofs) if name in TRUNK_DOFS]
        if cols and float(np.ptp(np.asarray(kf.q)[:, cols], axis=0).max()) > TRUNK_TURN:
            return seg
    return None


def is_free(ir: MotionIR, side: str, t0: float, t1: float) -> bool:
    """Whether the ``side`` arm has nothing to do over ``t0``-``t1``: no segment of its own
    (a reach, a contact, a hold, a wrench stroke) and its hand holds nothing."""
    for name in (f"{side}_arm", f"{side}_hand"):
        if any(s.start < t1 - EPS and s.end > t0 + EPS for s in ir.on_track(name)):
            return False
    return not any(g.start < t1 - EPS and end > t0 + EPS for g, _, end in _grasps(ir, side))


def free_arm_out(ir: MotionIR, reach: Reach, obstacles: Obstacles, side: str) -> None:
    """A free arm (``is_free``) that the reach's trunk turn carries through a model on the
    way (out of it at the reach's start and end): its shoulder and elbow keyed with the reach
    so that its hand and elbow bow away by one minimum-jerk bell (``bump``), the direction
    and peak whose least rigid moves need the least height, as a reach's own detour."""
    skel = ir.skeleton
    carrier = trunk_carrier(reach)
    if carrier is None or not is_free(ir, side, reach.t0, reach.t1):
        return
    arm = ArmCapsules(ir, [side], reach.t0, reach.t1)
    q = reach.path([s.keyframes for s in reach.segs])
    pose = forward(skel, q, *reach.root, with_axes=False)
    depth = arm.depth(obstacles, pose, reach.times)
    before = float(depth.max())
    if before <= 0.0 or depth[0] > -MARGIN or depth[-1] > -MARGIN:
        return  # clear, or in at an end: where it is, not the way, holds it there
    share = (reach.times - reach.t0) / (reach.t1 - reach.t0)
    inside = np.flatnonzero(depth > -MARGIN)
    inner = np.flatnonzero((share >= VIA_OFF_END - EPS) & (share <= 1.0 - VIA_OFF_END + EPS))
    at = forward(skel, q[inside], reach.root[0][inside], reach.root[1][inside], with_axes=False)
    shoulder = at.p[:, skel.joint_index(f"{side}_shoulder")].mean(axis=0)
    hand = site_positions(skel, at, f"{side}_hand").mean(axis=0)
    ranked = []
    for i, direction in enumerate(directions([], shoulder, hand)):
        moves = least_moves(arm, obstacles, at, reach.times[inside], direction)
        if np.isfinite(moves).all():
            peak, height = best_peak(moves, share, inside, inner)
            ranked.append((height, i, direction, peak))
    ranked.sort(key=lambda r: r[:2])
    names = [skel.dof_names[d] for d in carrying_dofs(skel, side)]
    idx = [skel.dof_index(n) for n in names]
    raw = reach.path([s.keyframes for s in reach.segs], smooth=False)
    was_body = body_depth(skel, pose, [side])
    best: tuple[float, Keyframes] | None = None
    for height, _, direction, peak in ranked[:TRIED]:
        rows = key_rows(reach, carrier, peak)
        lift = bump(share[rows], float(share[peak]))
        root = (reach.root[0][rows], reach.root[1][rows])
        moved = np.flatnonzero(lift > 1e-6)
        for scale in SCALES:
            offset = scale * height * lift[moved, None] * direction[None, :]
            solved = raw[rows].copy()
            solved[moved] = solve_via(skel, raw[rows][moved], (root[0][moved], root[1][moved]),
                                      [side], offset)  # fmt: skip
            trial = with_dofs(carrier.keyframes, reach.times[rows], raw[rows], solved, names,
                              idx, skel)  # fmt: skip
            keys = [trial if s is carrier else s.keyframes for s in reach.segs]
            pose_new = forward(skel, reach.path(keys), *reach.root, with_axes=False)
            if body_depth(skel, pose_new, [side]) > max(was_body, 0.0) + BODY_SLACK:
                continue
            after = float(arm.depth(obstacles, pose_new, reach.times).max())
            if best is None or after < best[0]:
                best = (after, trial)
            if after <= -MARGIN:
                break
        if best is not None and best[0] <= -MARGIN:
            break
    if best is not None and best[0] <= before - GAIN:
        carrier.keyframes = best[1]


def with_dofs(
    kf: Keyframes,
    times: FloatArray,
    raw: FloatArray,
    solved: FloatArray,
    names: list[str],
    idx: list[int],
    skel: Skeleton,
) -> Keyframes:
    """The carrier's keys at ``times`` (its own dofs from the path ``raw``) with the free
    arm's dofs ``names`` (columns ``idx``) from ``solved``, added or replaced."""
    dofs = list(kf.dofs) + [n for n in names if n not in kf.dofs]
    cols = [skel.dof_index(n) for n in dofs]
    q = raw[:, cols].copy()
    for n, d in zip(names, idx, strict=True):
        q[:, dofs.index(n)] = solved[:, d]
    return Keyframes(time=times, dofs=tuple(dofs) if isinstance(kf.dofs, tuple) else dofs, q=q)


def add_via(ir: MotionIR, reach: Reach, obstacles: Obstacles, arms: ArmCapsules) -> bool:
    """One via key at the reach's deepest sample, if one makes the path ``GAIN`` less deep;
    whether it was added."""
    skel = ir.skeleton
    keys = [s.keyframes for s in reach.segs]
    q = reach.path(keys)
    pose = forward(skel, q, *reach.root, with_axes=False)
    share = (reach.times - reach.t0) / (reach.t1 - reach.t0)
    raw = arms.depth(obstacles, pose, reach.times)
    if max(raw[0], raw[-1]) > END_INSIDE:
        return False  # in at an end: the pose there, not the way, holds the finding
    allowed = end_allowance(raw, share)
    depth = raw - allowed
    before = float(depth.max())
    if before <= -MARGIN:
        return False
    inner = (share >= VIA_OFF_END - EPS) & (share <= 1.0 - VIA_OFF_END + EPS)
    # the samples a detour must move, each by its least rigid move along a direction, and
    # the bell that gives each its move with the least height (the peak where it must be)
    inside = np.flatnonzero((depth > -MARGIN) & inner)
    if not inside.size:
        return False
    at = forward(skel, q[inside], reach.root[0][inside], reach.root[1][inside], with_axes=False)
    side = reach.sides[0]
    shoulder = at.p[:, skel.joint_index(f"{side}_shoulder")].mean(axis=0)
    hand = site_positions(skel, at, f"{side}_hand").mean(axis=0)
    normals = [
        np.asarray(n, dtype=float)
        for s in reach.segs
        for n in [s.goal.params.get("approach_normal") or s.goal.params.get("normal")]
        if n is not None
    ]
    ranked = []
    for i, direction in enumerate(directions(normals, shoulder, hand)):
        moves = least_moves(arms, obstacles, at, reach.times[inside], direction)
        if np.isfinite(moves).all():
            peak, height = best_peak(moves, share, inside, np.flatnonzero(inner))
            ranked.append((height, i, direction, peak))
    ranked.sort(key=lambda r: r[:2])
    was_length = hand_length(skel, pose, reach.sides)
    was_body = body_depth(skel, pose, reach.sides)
    was_ldlj = paced_ldlj(skel, q, pose, reach.sides)
    best: tuple[float, list[Keyframes]] | None = None
    for height, _, direction, peak in ranked[:TRIED]:
        for scale in SCALES:
            trial = bumped_keys(reach, peak, scale * height * direction)
            q_new = reach.path(trial)
            pose_new = forward(skel, q_new, *reach.root, with_axes=False)
            if hand_length(skel, pose_new, reach.sides) > MAX_LONGER * max(was_length, 0.05):
                break  # a larger move is longer still
            if body_depth(skel, pose_new, reach.sides) > max(was_body, 0.0) + BODY_SLACK:
                continue
            if paced_ldlj(skel, q_new, pose_new, reach.sides) < min(
                was_ldlj - LDLJ_LOSS, LDLJ_FLOOR
            ):
                break  # a larger detour is rougher still
            after = float((arms.depth(obstacles, pose_new, reach.times) - allowed).max())
            if best is None or after < best[0]:
                best = (after, trial)
            if after <= -MARGIN:
                break
        if best is not None and best[0] <= -MARGIN:
            break
    if best is None or best[0] > before - GAIN:
        return False
    for seg, kf in zip(reach.segs, best[1], strict=True):
        seg.keyframes = kf
    return True


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """Each reach's path between its keys bent around the models (the module docstring)."""
    del ctx
    if not ir.geometry or ir.skeleton is None:
        return ir
    state = PoseState(ir)
    obstacles = obstacles_of(ir, state)
    if obstacles is None:
        return ir
    for segs in groups(ir, "TA"):
        reach = reach_of(ir, state, segs)
        if reach is not None:
            plan(ir, reach, obstacles)
    return ir
