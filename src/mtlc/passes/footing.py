"""Pass 3b: where a walk stops, the feet and legs stand clear of the equipment (issue 20).

A walk goes to its site's ground point (in front of a raised site: ``semantics.stand``) and
arrives facing its work; the front end knows nothing of the scene's models, so a site in front
of a bench (``bench_front``) put a 5th
percentile woman's toes 24 mm into the bench and her feet 56 mm in by the depth of their far
ends (MT0515). Before the gait is made, each walk's end is checked: the standing legs (feet,
shanks and thighs: ``mtlc.body.capsules``' collision capsules of the comfortable pose, turned
to the arrival heading) against every model. Where any goes into one, the stance is moved
back, along the way the walk came (the approach) or, if that clears with less, straight back
from the heading it faces, by the least whole ``PUSH_STEP`` that leaves ``FOOT_CLEARANCE``
between the legs and every model, at most ``MAX_PUSH``. A stance already clear stays, however
close: stepping back lengthens every reach after it (1 cm back at the fuel filter's bay tipped
the 50th-percentile woman's balance, MT0502, at one more line). The root plan moves with it
until the next walk (the reaches after it start from there). A stance that cannot be cleared
is left where it was: verify reports the legs in the model (MT0515). The steps on the way are
not planned around models.

Only scenes with models pay: without one the pass returns at once.
"""

from __future__ import annotations

import math

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.body.capsules import capsule_segments, collision_capsules
from mtlc.geometry.clearance import scene_indices
from mtlc.geometry.distance import MeshIndex
from mtlc.ir.model import FloatArray, MotionIR, Segment
from mtlc.passes.context import PassContext

FOOT_CLEARANCE = 0.01  # m between a standing leg's surface and the equipment
PUSH_STEP = 0.01  # m: the stance moves back in steps of this
MAX_PUSH = 0.5  # m: farther back than this the walk's site is not where the task stands
LEG_PARTS = ("foot", "shank", "thigh")
SOLES = ("r_heel", "r_toe", "l_heel", "l_toe")
EPS = 1e-9


def standing_legs(ir: MotionIR) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The standing legs' capsules in the body's ground frame (root over the origin, heading
    0, soles on the ground): axis ends (C, 3) and radii (C,)."""
    skel = ir.skeleton
    caps = tuple(c for c in collision_capsules(skel) if c.name.split(" ")[-1] in LEG_PARTS)
    q = np.asarray(skel.q_comfort, dtype=float)
    pose = forward(skel, q, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), with_axes=False)
    sole = min(float(site_positions(skel, pose, s)[..., 1].min()) for s in SOLES)
    a, b, radii = capsule_segments(skel, pose, caps)
    lift = np.array([0.0, ir.ground - sole, 0.0])
    return a.reshape(-1, 3) + lift, b.reshape(-1, 3) + lift, radii


def _placed(points: FloatArray, at: FloatArray, heading: float) -> FloatArray:
    """Body-frame points turned by ``heading`` about +Y and moved over ``at`` (x, z)."""
    c, s = math.cos(heading), math.sin(heading)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return points @ turn.T + np.array([at[0], 0.0, at[2]])


def leg_clearance(
    legs: tuple[FloatArray, FloatArray, FloatArray],
    indices: dict[str, MeshIndex],
    at: FloatArray,
    heading: float,
) -> float:
    """The smallest clearance (m) of the standing legs at ``at`` facing ``heading``."""
    a, b, radii = legs
    pa, pb = _placed(a, at, heading), _placed(b, at, heading)
    least = math.inf
    for index in indices.values():
        # every segment asked exactly (six of them): a horizon's lower bound less a thigh's
        # radius read as a thigh 2 cm into the fuel filter's bay, 33 cm from it
        d = index.segment_distance(pa, pb) - radii
        least = min(least, float(d.min()))
    return least


def clear_push(
    legs: tuple[FloatArray, FloatArray, FloatArray],
    indices: dict[str, MeshIndex],
    at: FloatArray,
    heading: float,
    directions: list[FloatArray],
) -> FloatArray | None:
    """The least move (3,) along one of ``directions`` (unit, horizontal) that puts the legs
    ``FOOT_CLEARANCE`` clear; None when none does within ``MAX_PUSH``."""
    steps = round(MAX_PUSH / PUSH_STEP)
    for k in range(1, steps + 1):
        for d in directions:
            move = d * k * PUSH_STEP
            if leg_clearance(legs, indices, at + move, heading) >= FOOT_CLEARANCE:
                return move
    return None


def _directions(start: FloatArray, goal: FloatArray, heading: float) -> list[FloatArray]:
    """Back along the way the walk came, then straight back from the heading it faces."""
    out = []
    way = np.array([goal[0] - start[0], 0.0, goal[2] - start[2]])
    if np.linalg.norm(way) > 1e-6:
        out.append(-way / np.linalg.norm(way))
    out.append(-np.array([math.sin(heading), 0.0, math.cos(heading)]))
    return out


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    """Move each walk's end (and the plan after it, until the next walk) out of the models."""
    del ctx
    plan = ir.root_plan
    if not ir.geometry or plan is None or ir.skeleton is None:
        return ir
    indices = scene_indices([m for m in ir.geometry if len(m.faces)])
    if not indices:
        return ir
    legs = standing_legs(ir)
    walks: list[Segment] = sorted(
        (s for s in ir.segments if s.kind == "locomotion" and s.end - s.start > EPS),
        key=lambda s: s.start,
    )
    for k, walk in enumerate(walks):
        goal, heading = plan.at(walk.end)
        goal, heading = np.asarray(goal, dtype=float), float(heading)
        if leg_clearance(legs, indices, goal, heading) >= 0.0:
            continue  # clear already: a stance that touches nothing is the task's to keep
        start, _ = plan.at(walk.start)
        move = clear_push(legs, indices, goal, heading, _directions(start, goal, heading))
        if move is None:
            continue  # verify reports the legs in the model (MT0515)
        until = walks[k + 1].end if k + 1 < len(walks) else math.inf
        same = np.all(np.abs(plan.position - goal) < 1e-9, axis=1)
        knots = (plan.time >= walk.end - EPS) & (plan.time < until - EPS) & same
        plan.position[knots] += move
        walk.result["stance_moved"] = [round(float(x), 6) for x in move]
    return ir
