"""Motion metrics on any sampled motion: what the issue's acceptance numbers are measured with.

The figures a claim rests on (penetration, balance margin, contact error, limits, grip drift,
hands inside the body) are measured once, by the verify pass, on the output frames, and
``compute_metrics`` reads them from ``MotionIR.verification`` (docs/metrics.md); foot skating and
smoothness are measured here. The geometry helpers (support points, hulls, stance) read plain
data (frames, a skeleton, the ground height, the segments), so the verify pass and the balance
pass share them. This module imports no pass. Units are SI inside (m, m/s, rad); the table
shows mm, cm/s and degrees.

Smoothness is the log dimensionless jerk (LDLJ) of a hand's path, velocity-based:
``LDLJ = −ln( T³ / v_peak² · ∫ |d³x/dt³|² dt )`` (Balasubramanian, Melendez-Calderon, Roby-Brami
& Burdet 2015, "On the analysis of movement smoothness", J NeuroEng Rehabil 12:112; the
dimensionless jerk of Hogan & Sternad 2009, "Sensitivity of smoothness measures to movement
duration, amplitude, and arrests", J Motor Behavior 41:529). Higher is smoother: a
minimum-jerk point-to-point movement scores −ln(720/1.875²) ≈ −5.32.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from dataclasses import dataclass, field
from io import StringIO
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mtlc.body import site_positions
from mtlc.body.kinematics import output_pose, repeated_rows
from mtlc.ir.model import MotionIR
from mtlc.loads import carried_com

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

FEET = ("r", "l")
FOOT_POINT_NAMES = ("heel", "toe", "ball_med", "ball_lat")
CONTACT_TOL = 0.01  # a foot point within 1 cm of the ground is on it (stance, skating)
# what bears weight, strictly: a point supports only within 2 mm of the floor or of the site
# it rests on (docs/metrics.md, "Support")
SUPPORT_TOL = 0.002
# a kneeling knee bears weight on its front, half a knee's depth (5 cm, as the posture pass
# places it) below the joint centre: a knee centre this close to the ground supports
KNEE_DEPTH = 0.05
KNEE_CONTACT = KNEE_DEPTH + SUPPORT_TOL
KNEE_HALF_WIDTH = 0.025  # m: half a patella's breadth (about 5 cm in adults)
HAND_SITES = ("r_hand", "l_hand", "r_fingertip", "l_fingertip")

# Acceptance thresholds from the issue ("Motion metrics").
MAX_PENETRATION = 1e-3  # m
MAX_SKATING = 0.02  # m/s, feet in stance
MIN_SUPPORT_MARGIN = 0.0  # m, static postures
MAX_CONTACT_ERROR = 1e-3  # m, where the site is reachable
MAX_GRIP_DRIFT = 1e-3  # m, a closed hand on a part nothing moves
MAX_INSIDE_BODY = 1e-3  # m, a hand's or forearm's axis inside the trunk or a thigh


# -- geometry --------------------------------------------------------------------------------


class Hull(NamedTuple):
    """Candidate edges of support polygons (every pair of touching points), per frame."""

    a: FloatArray  # (N, E, 2) edge start
    d: FloatArray  # (N, E, 2) edge vector
    safe: FloatArray  # (N, E) edge length (1 where degenerate)
    edge: BoolArray  # (N, E) the pair is a hull edge
    orient: FloatArray  # (N, E) +1/−1: the side the hull is on; 0: all points on the line
    pts: FloatArray  # (N, P, 2)
    ok: BoolArray  # (N, P)

    def take(self, rows: NDArray[np.intp]) -> Hull:
        return Hull(*(x[rows] for x in self))


def hull(points: FloatArray, valid: BoolArray) -> Hull:
    """The convex hulls of ``points`` (N, P, 2) where ``valid`` (N, P), vectorised over frames.

    With P ≤ 22 points every pair is tried as an edge: an edge has all the other points on one
    side. Computed once when the same support serves many centres of mass.
    """
    pts = np.asarray(points, dtype=float)
    ok = np.asarray(valid, dtype=bool)
    used = ok.any(axis=0)
    if used.sum() >= 3 and not used.all():  # points that never touch (knees) only cost pairs
        pts, ok = pts[:, used], ok[:, used]
    ii, jj = np.triu_indices(ok.shape[1], 1)
    a, b = pts[:, ii], pts[:, jj]  # (N, E, 2)
    d = b - a
    length = np.hypot(d[..., 0], d[..., 1])
    pair_ok = ok[:, ii] & ok[:, jj] & (length > 1e-9)
    safe = np.where(length > 1e-9, length, 1.0)
    # side of every point k to every pair's line (N, E, P), in metres
    rel = pts[:, None, :, :] - a[:, :, None, :]
    side = (d[..., None, 0] * rel[..., 1] - d[..., None, 1] * rel[..., 0]) / safe[..., None]
    eps = 1e-9
    others = ok[:, None, :]
    pos = (others & (side > eps)).any(axis=-1)
    neg = (others & (side < -eps)).any(axis=-1)
    edge = pair_ok & ~(pos & neg)
    orient = np.where(pos, 1.0, np.where(neg, -1.0, 0.0))
    return Hull(a, d, safe, edge, orient, pts, ok)


HULL_EPS = 1e-9  # m: as ``hull``


def grouped_hull(points: FloatArray, valid: BoolArray) -> Hull:
    """``hull``, the same edges, computed per set of touching points: frames with
    the same contacts share which pairs to try, and each pair is tested against the touching
    points only (8 of 22 candidates when standing), not every pair against every point.
    Each frame keeps only its edges (first, padded with non-edges to the most edges a frame
    has): ``hull_margin`` reads nothing else, and a hull has a few of the pairs.

    Each group's pairs are formed for its own frames only (the edge vectors of all 231 pairs
    of every frame were most of the cost: 32,000 frames made 120 MB of them); a frame's edges,
    their order and their numbers are what ``hull`` gives it, and the padding is a non-edge
    (``edge`` False, ``orient`` 0, ``safe`` 1) that ``hull_margin`` masks out."""
    pts = np.asarray(points, dtype=float)
    ok = np.asarray(valid, dtype=bool)
    used = ok.any(axis=0)
    if used.sum() >= 3 and not used.all():
        pts, ok = pts[:, used], ok[:, used]
    runs = repeated_rows(pts, ok)
    if runs is not None:  # a run of identical frames (a hold) has one hull: found once
        heads, at = runs
        h = grouped_hull(pts[heads], ok[heads])  # the same points used: the rows are these
        return Hull(h.a[at], h.d[at], h.safe[at], h.edge[at], h.orient[at], pts, ok)
    n = len(pts)
    ii, jj = np.triu_indices(ok.shape[1], 1)
    # frames grouped by their set of touching points, a bit each in one int (``np.unique`` of
    # the rows themselves sorts them as byte strings, a tenth of the whole): with 64 points or
    # more, by the rows
    if ok.shape[1] < 64:
        keys = ok.astype(np.int64) @ (np.int64(1) << np.arange(ok.shape[1], dtype=np.int64))
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(ok, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    by_group = np.argsort(inverse, kind="stable")
    bounds = np.searchsorted(inverse[by_group], np.arange(len(first) + 1))
    groups = []  # (rows, each row's edges first: a, d, safe, edge, orient)
    keep = 1
    for m, mask in enumerate(ok[first]):
        rows = by_group[bounds[m] : bounds[m + 1]]
        cols = np.flatnonzero(mask)
        pairs = np.flatnonzero(mask[ii] & mask[jj])
        if pairs.size == 0:
            continue
        pi, pj = ii[pairs], jj[pairs]
        aa = pts[rows][:, pi]
        dd = pts[rows][:, pj] - aa
        length = np.hypot(dd[..., 0], dd[..., 1])
        pair_ok = length > 1e-9  # both points touch: the group's pairs are of its points
        safe = np.where(pair_ok, length, 1.0)
        # the side of every point to every pair's line: d × (p − a) = d × p − d × a
        normal = np.stack([-dd[..., 1], dd[..., 0]], axis=-1)  # (R, E, 2)
        side = normal @ np.swapaxes(pts[np.ix_(rows, cols)], 1, 2)  # (R, E, K)
        side -= (dd[..., 0] * aa[..., 1] - dd[..., 1] * aa[..., 0])[..., None]
        tol = (HULL_EPS * safe)[..., None]  # HULL_EPS metres from the line
        pos, neg = (side > tol).any(axis=-1), (side < -tol).any(axis=-1)
        edge = pair_ok & ~(pos & neg)
        orient = np.where(pos, 1.0, np.where(neg, -1.0, 0.0))
        groups.append((rows, aa, dd, safe, edge, orient))
        keep = max(keep, int(edge.sum(axis=1).max(initial=0)))
    out_a, out_d = np.zeros((n, keep, 2)), np.zeros((n, keep, 2))
    out_safe, out_orient = np.ones((n, keep)), np.zeros((n, keep))
    out_edge = np.zeros((n, keep), dtype=bool)
    for rows, aa, dd, safe, edge, orient in groups:
        k = min(keep, edge.shape[1])
        order = np.argsort(~edge, axis=1, kind="stable")[:, :k]
        out_a[rows, :k] = np.take_along_axis(aa, order[..., None], axis=1)
        out_d[rows, :k] = np.take_along_axis(dd, order[..., None], axis=1)
        out_safe[rows, :k] = np.take_along_axis(safe, order, axis=1)
        out_edge[rows, :k] = np.take_along_axis(edge, order, axis=1)
        out_orient[rows, :k] = np.take_along_axis(orient, order, axis=1)
    return Hull(out_a, out_d, out_safe, out_edge, out_orient, pts, ok)


def hull_margin(h: Hull, com: FloatArray) -> FloatArray:
    """Signed distance (N,) of ``com`` (N, 2) to each frame's hull (see ``support_margin``)."""
    c = np.asarray(com, dtype=float)
    rc = c[:, None, :] - h.a
    line = (h.d[..., 0] * rc[..., 1] - h.d[..., 1] * rc[..., 0]) / h.safe
    inward = h.orient * line  # positive toward the hull's inside
    t = np.clip(np.einsum("nek,nek->ne", rc, h.d) / (h.safe**2), 0.0, 1.0)
    seg = np.hypot(*np.moveaxis(rc - t[..., None] * h.d, -1, 0))
    seg_d = np.where(h.edge, seg, np.inf).min(axis=1)
    lone = np.hypot(*np.moveaxis(h.pts - c[:, None, :], -1, 0))
    pt_d = np.where(h.ok, lone, np.inf).min(axis=1)
    outside_d = np.minimum(seg_d, pt_d)
    sides = h.edge & (h.orient != 0)
    inside = sides.any(axis=1) & np.where(sides, inward >= 0.0, True).all(axis=1)
    inside_d = np.where(sides, inward, np.inf).min(axis=1)
    out = np.where(inside, inside_d, -outside_d)
    return np.where(h.ok.any(axis=1), out, np.nan)


def support_margin(
    points: FloatArray, valid: BoolArray, com: FloatArray, h: Hull | None = None
) -> FloatArray:
    """Signed distance (N,) of ground points ``com`` (N, 2) to the convex hull of ``points``.

    ``points`` (N, P, 2) are the ground-plane (x, z) coordinates of the contact points, ``valid``
    (N, P) which of them touch (see ``support``). Positive inside (distance to the nearest
    edge), negative outside (distance to the polygon); a hull of one point or a segment has no
    inside. NaN where no point touches. ``h``: the hull, when already computed.
    """
    return hull_margin(hull(points, valid) if h is None else h, com)


def support_push(
    points: FloatArray, valid: BoolArray, com: FloatArray, margin: float, h: Hull | None = None
) -> FloatArray:
    """Ground-plane move (N, 2) that brings ``com`` to ``margin`` inside the support, about.

    Inside, along the nearest edge's inward normal by what is missing; outside, toward the
    nearest point of the hull plus ``margin``. Exact for one edge; callers iterate.
    """
    pts = np.asarray(points, dtype=float)
    ok = np.asarray(valid, dtype=bool)
    c = np.asarray(com, dtype=float)
    m = support_margin(pts, ok, c, h)
    # centroid of the touching points: a direction that always points inward
    w = ok.astype(float)
    cnt = np.maximum(w.sum(axis=1), 1.0)
    centroid = np.einsum("np,npk->nk", w, np.nan_to_num(pts)) / cnt[:, None]
    to_c = centroid - c
    dist = np.hypot(to_c[:, 0], to_c[:, 1])
    u = to_c / np.maximum(dist, 1e-12)[:, None]
    need = np.where(np.isnan(m), 0.0, np.maximum(margin - m, 0.0))
    need = np.minimum(need, dist)  # never past the centre of the support
    return u * need[:, None]


# -- contact information ---------------------------------------------------------------------


STEPPING_KINDS = ("locomotion", "posture")  # segments whose result records footsteps


def spans_mask(
    time: FloatArray, lo: FloatArray, hi: FloatArray, closed: tuple[bool, bool] = (True, True)
) -> BoolArray:
    """(N,) times inside any of the spans ``lo``–``hi`` (S,), each end closed (``<=``) or open
    (``<``) as ``closed`` says: the same comparisons as a mask per span OR-ed together, by
    bisection in the sorted times and a running count of the spans open at each time (a mask
    per span cost a pass over every frame for every footstep or contact, per call)."""
    t = np.asarray(time, dtype=float)
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    order = np.argsort(t, kind="stable")
    ts = t[order]
    first = np.searchsorted(ts, lo, side="left" if closed[0] else "right")
    stop = np.searchsorted(ts, hi, side="right" if closed[1] else "left")
    keep = first < stop
    count = np.zeros(len(ts) + 1, dtype=np.int64)
    np.add.at(count, first[keep], 1)
    np.add.at(count, stop[keep], -1)
    mask = np.zeros(len(t), dtype=bool)
    mask[order] = np.cumsum(count[:-1]) > 0
    return mask


def swing_spans(ir: MotionIR) -> list[tuple[FloatArray, FloatArray]]:
    """Per foot (r, l), the (lift, land) times of its steps (``result["steps"]`` of the walks
    and stepping kneels): what ``foot_stance`` reads, for a caller that asks at many times."""
    spans: list[tuple[list[float], list[float]]] = [([], []) for _ in FEET]
    for seg in ir.segments:
        if seg.kind not in STEPPING_KINDS:
            continue
        for step in seg.result.get("steps", ()) or ():
            lifts, lands = spans[FEET.index(str(step["foot"])[0])]
            lifts.append(float(step["t_lift"]))
            lands.append(float(step["t_land"]))
    return [(np.array(a, dtype=float), np.array(b, dtype=float)) for a, b in spans]


def foot_stance(
    ir: MotionIR, time: FloatArray, swings: list[tuple[FloatArray, FloatArray]] | None = None
) -> BoolArray:
    """(N, 2) which feet (r, l) stand at each time: both, except a foot in the air in a step.

    Walks (locomotion segments) and the stepping kneel (a posture) record their footsteps in
    ``result["steps"]`` (foot, t_lift, t_land); otherwise both feet stand. ``swings``:
    ``swing_spans(ir)``, for a caller that asks many times.
    """
    t = np.asarray(time, dtype=float)
    stance = np.ones((len(t), 2), dtype=bool)
    for k, (lift, land) in enumerate(swing_spans(ir) if swings is None else swings):
        if lift.size:  # in the air strictly between lift and landing
            stance[:, k] = ~spans_mask(t, lift + 1e-9, land - 1e-9, closed=(False, False))
    return stance


def rolling_points(ir: MotionIR, time: FloatArray) -> BoolArray:
    """(N, 8) sole points lifting off as the foot rolls over its toe.

    Between a step's ``t_heel_off`` and ``t_lift`` the foot pivots about its toe: heel and balls
    rise and swing, the toe stays put. The stepping kneel records such windows as
    ``result["rolls"]`` (foot, from, to): a foot on its toes. Only the toe is then planted, so
    only it can skate.
    """
    t = np.asarray(time, dtype=float)
    out = np.zeros((len(t), len(FEET) * len(FOOT_POINT_NAMES)), dtype=bool)
    toe = FOOT_POINT_NAMES.index("toe")

    def roll(foot: str, start: float, end: float) -> None:
        k = FEET.index(foot[0])
        inside = (t >= start) & (t <= end)
        for j in range(len(FOOT_POINT_NAMES)):
            if j != toe:
                out[inside, k * len(FOOT_POINT_NAMES) + j] = True

    for seg in ir.segments:
        if seg.kind not in STEPPING_KINDS:
            continue
        for step in seg.result.get("steps", ()) or ():
            if "t_heel_off" in step:
                roll(str(step["foot"]), float(step["t_heel_off"]), float(step["t_lift"]))
        for window in seg.result.get("rolls", ()) or ():
            roll(str(window["foot"]), float(window["from"]), float(window["to"]))
    return out


def walk_spans(ir: MotionIR) -> tuple[FloatArray, FloatArray]:
    """(start, end) of the locomotion segments, for a caller that asks ``walking`` many times."""
    walks = [seg for seg in ir.segments if seg.kind == "locomotion"]
    starts = np.array([seg.start for seg in walks], dtype=float)
    return starts, np.array([seg.end for seg in walks], dtype=float)


def walking(
    ir: MotionIR, time: FloatArray, spans: tuple[FloatArray, FloatArray] | None = None
) -> BoolArray:
    """(N,) frames inside a locomotion segment. ``spans``: ``walk_spans(ir)``, if known."""
    start, end = walk_spans(ir) if spans is None else spans
    return spans_mask(time, start - 1e-9, end + 1e-9)


def foot_points(skel: Any, pose: Any) -> FloatArray:
    """(N, 8, 3) world positions of the four sole points of the right, then the left foot."""
    names = [f"{s}_{p}" for s in FEET for p in FOOT_POINT_NAMES]
    return site_positions(skel, pose, names)


def contact_mask(
    feet: FloatArray, stance: BoolArray, ground: float, tol: float = CONTACT_TOL
) -> BoolArray:
    """(N, 8) sole points on the ground: their foot stands and they are within ``tol`` of it
    (1 cm: the foot is down, for skating; ``support`` asks ``SUPPORT_TOL``, what bears weight)."""
    near = feet[..., 1] - ground <= tol
    return near & np.repeat(stance, len(FOOT_POINT_NAMES), axis=1)


def forefoot_patch(skel: Any, pose: Any) -> FloatArray:
    """(N, 8, 3) the forefoot a foot stands on when its heel is up: four corners per foot
    (right, then left), the toe tip ± half the ball's breadth across the foot and the same
    points the ball-to-toe length behind it, flat on the ground along the foot's heading.

    A point supports only where it touches (issue 18): these virtual corners never count. The
    foot now has a toe joint, and a heel-up foot that bends its toes puts its real ball points
    and toe tip down, which ``support`` counts as sole points; the corners stay for the slot
    layout. See docs/metrics.md, "Support".
    """
    out = []
    for side in FEET:
        toe, heel, med, lat = (
            site_positions(skel, pose, f"{side}_{n}")
            for n in ("toe", "heel", "ball_med", "ball_lat")
        )
        ahead = (toe - heel)[..., [0, 2]]
        ahead /= np.maximum(np.linalg.norm(ahead, axis=-1, keepdims=True), 1e-9)
        across = np.stack([ahead[..., 1], -ahead[..., 0]], axis=-1)
        half = 0.5 * np.linalg.norm(med - lat, axis=-1, keepdims=True)
        length = np.linalg.norm(toe - 0.5 * (med + lat), axis=-1, keepdims=True)
        tip = toe[..., [0, 2]]
        for back in (0.0, 1.0):
            for sign in (1.0, -1.0):
                xz = tip - back * length * ahead + sign * half * across
                out.append(np.stack([xz[..., 0], toe[..., 1], xz[..., 1]], axis=-1))
    return np.stack(out, axis=-2)


def knee_patch(skel: Any, pose: Any) -> FloatArray:
    """(N, 4, 3) where a kneeling knee bears weight: its centre ± ``KNEE_HALF_WIDTH`` along
    the knee's axis (right knee, then left): the patella and the tibial tuberosity below it
    are about a patella's breadth wide."""
    out = []
    for side in FEET:
        j = skel.joint_index(f"{side}_knee")
        axis = pose.R[..., j, :, 0]  # the knee flexes about its joint frame's X
        centre = pose.p[..., j, :]
        for sign in (1.0, -1.0):
            out.append(centre + sign * KNEE_HALF_WIDTH * axis)
    return np.stack(out, axis=-2)


# support point slots: 8 sole points, 8 forefoot corners, 4 knee points, 2 hands
SOLE_SLOTS = slice(0, 8)
FOREFOOT_SLOTS = slice(8, 16)
KNEE_SLOTS = slice(16, 20)
HAND_SLOTS = slice(20, 22)
ARM_TRACKS = {"r_hand": "r_arm", "l_hand": "l_arm"}


class RestWindows(NamedTuple):
    """One hand's rest windows (``hand_rest_windows``): ``lo <= t < hi``, and the site's
    position (W, 3) where ``placed`` (a goal with no position is measured against nothing)."""

    lo: FloatArray
    hi: FloatArray
    position: FloatArray
    placed: BoolArray


def hand_rest_windows(ir: MotionIR) -> list[RestWindows]:
    """Per hand (r, l), the windows ``hand_contacts`` reads: from the end of each reached TO
    segment of the hand itself until the next segment on its arm track starts (or forever).
    What depends on the segments only, for a caller that asks at many times."""
    out = []
    for hand, track in ARM_TRACKS.items():
        segs = sorted(ir.on_track(track), key=lambda s: s.start)
        starts = [s.start for s in segs]
        lo: list[float] = []
        hi: list[float] = []
        position: list[Any] = []
        for i, seg in enumerate(segs):
            if seg.kind != "TO" or not _reachable(seg.result):  # short of its site: no rest
                continue
            if seg.goal.effector != hand:  # a tool's tip on its fastener: not a support
                continue
            j = bisect_left(starts, seg.end - 1e-9, lo=i + 1)  # the first later start after it
            lo.append(seg.end - 1e-9)
            hi.append((starts[j] if j < len(starts) else math.inf) - 1e-9)
            position.append(seg.goal.position)
        placed = np.array([p is not None for p in position], dtype=bool)
        xyz = np.full((len(position), 3), np.nan)
        for w, p in enumerate(position):
            if p is not None:
                xyz[w] = np.asarray(p, dtype=float)
        out.append(RestWindows(np.array(lo, dtype=float), np.array(hi, dtype=float), xyz, placed))
    return out


def hand_contacts(
    ir: MotionIR, time: FloatArray, pose: Any = None, windows: list[RestWindows] | None = None
) -> BoolArray:
    """(N, 2) which hands (r, l) rest on a site: from the end of a TO segment of the hand (not
    of a tool's tip) until the next segment on the same arm track starts, or the end of the
    motion, and, given the ``pose`` at ``time``, only while the hand is within ``SUPPORT_TOL``
    of that site (a hand lifted off it, or short of it, bears no weight). ``windows``:
    ``hand_rest_windows(ir)``, for a caller that asks many times."""
    t = np.asarray(time, dtype=float)
    out = np.zeros((len(t), 2), dtype=bool)
    skel = ir.skeleton
    if windows is None:
        windows = hand_rest_windows(ir)
    order = np.argsort(t, kind="stable")
    ts = t[order]
    for k, (hand, rest) in enumerate(zip(ARM_TRACKS, windows, strict=True)):
        if rest.lo.size == 0:
            continue
        if pose is None or skel is None:
            out[:, k] = spans_mask(t, rest.lo, rest.hi, closed=(True, False))
            continue
        # each window's frames as a range of the sorted times, all ranges at once: the hand's
        # distance to its window's site at every frame of every window
        first = np.searchsorted(ts, rest.lo[rest.placed], side="left")
        stop = np.searchsorted(ts, rest.hi[rest.placed], side="left")
        count = np.maximum(stop - first, 0)
        if not count.any():
            continue
        offset = np.repeat(first - (np.cumsum(count) - count), count)
        rows = order[np.arange(int(count.sum())) + offset]
        at = site_positions(skel, pose, hand)[rows]
        gap = np.linalg.norm(at - np.repeat(rest.position[rest.placed], count, axis=0), axis=-1)
        out[rows[gap <= SUPPORT_TOL], k] = True
    return out


def support(
    skel: Any, pose: Any, stance: BoolArray, ground: float, hands: BoolArray | None = None
) -> tuple[FloatArray, BoolArray]:
    """Ground-plane support points (N, 22, 2) and which bear weight (N, 22).

    A point supports only where it touches: within ``SUPPORT_TOL`` (2 mm) of the floor, or of
    the site it rests on. The eight sole points of a standing foot within ``SUPPORT_TOL`` of
    the ground (a foot on its toes stands on the balls and toe tip that touch: the toes bend);
    each kneeling knee (its front, ``KNEE_DEPTH`` below the centre, within ``SUPPORT_TOL`` of
    the ground) over its breadth (``knee_patch``); and, where ``hands`` (N, 2) says so
    (``hand_contacts`` with the pose: within ``SUPPORT_TOL`` of its site), the grip point of a
    hand resting on a site. Slots: ``SOLE_SLOTS``, ``FOREFOOT_SLOTS`` (kept for the layout;
    the virtual forefoot of ``forefoot_patch`` never bears weight), ``KNEE_SLOTS``,
    ``HAND_SLOTS``.
    """
    feet = foot_points(skel, pose)
    soles = contact_mask(feet, stance, ground, SUPPORT_TOL)
    fore = forefoot_patch(skel, pose)
    knees = pose.p[..., [skel.joint_index("r_knee"), skel.joint_index("l_knee")], :]
    kneeling = knees[..., 1] - ground <= KNEE_CONTACT
    grips = site_positions(skel, pose, list(ARM_TRACKS))
    resting = np.zeros(kneeling.shape, dtype=bool) if hands is None else np.asarray(hands, bool)
    pts = np.concatenate([feet, fore, knee_patch(skel, pose), grips], axis=-2)
    ok = np.concatenate(
        [
            soles,
            np.zeros(fore.shape[:-1], dtype=bool),
            np.repeat(kneeling, 2, axis=-1),
            resting,
        ],
        axis=-1,
    )
    return pts[..., [0, 2]], ok


def touching_support(ir: MotionIR, pose: Any, time: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Which points support in each frame: the one definition (docs/metrics.md, "Support").

    ``support`` of every foot (a sole point bears weight where it is within ``SUPPORT_TOL`` of
    the floor, whatever the steps' records say: the frames decide, as a check of the output
    files would), the kneeling knees, and the hands within ``SUPPORT_TOL`` of the site they rest
    on (``hand_contacts`` with the pose). verify measures balance on it, and the smoothing
    pass's check and the preview, ``--metrics``, ``lint`` and ``report`` read the same figure.
    """
    t = np.asarray(time, dtype=float)
    every_foot = np.ones((len(t), len(FEET)), dtype=bool)
    return support(ir.skeleton, pose, every_foot, ir.ground, hand_contacts(ir, t, pose))


def balance_margin(ir: MotionIR, pose: Any, time: FloatArray) -> FloatArray:
    """(N,) margin of the centre of mass (the body's, with what the hands hold and carry:
    ``carried_com``) over the hull of ``touching_support``; negative outside, NaN where
    nothing touches. The figure verify stores as ``Verification.support_margin``."""
    pts, ok = touching_support(ir, pose, time)
    return hull_margin(grouped_hull(pts, ok), carried_com(ir, pose, time)[:, [0, 2]])


# -- the metrics -----------------------------------------------------------------------------


BODY_SITES = (
    *(f"{s}_{p}" for s in FEET for p in FOOT_POINT_NAMES),
    *("r_hand", "l_hand", "r_foot", "l_foot", "r_fingertip", "l_fingertip"),
)


def lowest_point(skel: Any, pose: Any) -> FloatArray:
    """(N,) height of the lowest body point: every joint centre, sole point, hand, foot and
    fingertip."""
    sites = site_positions(skel, pose, list(BODY_SITES))[..., 1].min(axis=-1)
    return np.minimum(pose.p[..., 1].min(axis=-1), sites)


def penetration(skel: Any, pose: Any, ground: float) -> FloatArray:
    """(N,) depth of the lowest body point below the ground (m, 0 when nothing is below)."""
    return np.maximum(ground - lowest_point(skel, pose), 0.0)


def foot_skating(feet: FloatArray, contact: BoolArray, time: FloatArray) -> FloatArray:
    """(N-1, 8) horizontal speed (m/s) of each sole point touching at both ends of a frame step.

    NaN where the point does not touch at both frames. A heel rising off the ground stops
    counting; the toe it pivots on does not slide, so rolling is not skating.
    """
    dt = np.diff(np.asarray(time, dtype=float))
    dxz = np.diff(feet[..., [0, 2]], axis=0)
    speed = np.hypot(dxz[..., 0], dxz[..., 1]) / np.maximum(dt, 1e-12)[:, None]
    both = contact[1:] & contact[:-1]
    return np.where(both, speed, np.nan)


def ldlj(path: FloatArray, time: FloatArray) -> float:
    """Log dimensionless jerk (velocity-based) of a path (T, 3); NaN if it barely moves."""
    x = np.asarray(path, dtype=float)
    t = np.asarray(time, dtype=float)
    if len(t) < 6:
        return math.nan
    v = np.gradient(x, t, axis=0)
    a = np.gradient(v, t, axis=0)
    j = np.gradient(a, t, axis=0)
    vpeak = float(np.linalg.norm(v, axis=1).max())
    if vpeak < 1e-6:
        return math.nan
    duration = float(t[-1] - t[0])
    j2 = np.einsum("ti,ti->t", j, j)
    integral = float(np.sum(0.5 * (j2[1:] + j2[:-1]) * np.diff(t)))
    if integral <= 0.0:
        return math.nan
    return -math.log(duration**3 / vpeak**2 * integral)


@dataclass
class ContactError:
    """Effector-to-site distance where one goal ends (``Verification.contacts``)."""

    effector: str
    site: str
    time: float
    error: float  # m, at the first output frame at or after the goal's end
    reachable: bool  # the solver's claim
    shortfall: float = 0.0  # m, closest approach over the goal's frames


@dataclass
class Metrics:
    """What ``compute_metrics`` reports; SI units (m, m/s, degrees only for limits)."""

    frames: int
    duration: float
    penetration: float  # m, deepest body point below the ground over all frames
    penetration_time: float
    foot_skating: float  # m/s, fastest sliding sole point in contact (NaN: never in contact)
    support_margin: FloatArray  # (N,) m, signed, NaN where no point touches
    static: BoolArray  # (N,) frames outside walking
    support_margin_static: float  # m, minimum over static frames (NaN: none)
    contact_errors: list[ContactError] = field(default_factory=list)
    limit_count: int = 0
    limit_worst_deg: float = 0.0
    limit_worst_dof: str = ""
    ldlj: dict[str, list[tuple[str, float]]] = field(default_factory=dict)  # hand -> (label, v)
    grip_drift: float = 0.0  # m, the most a closed hand moves while nothing moves its part
    inside_body: float = 0.0  # m, deepest hand or forearm axis inside the trunk or a thigh
    penetration_by_class: dict[str, float] = field(default_factory=dict)  # class -> m

    @property
    def contact_error(self) -> float:
        """Largest hand-to-site distance over reachable contacts (m; 0 when there are none)."""
        errs = [c.error for c in self.contact_errors if c.reachable]
        return max(errs, default=0.0)

    @property
    def ldlj_worst(self) -> float:
        vals = [v for per in self.ldlj.values() for _, v in per if not math.isnan(v)]
        return min(vals, default=math.nan)

    def passes(self) -> dict[str, bool]:
        """The issue's acceptance checks, by metric."""
        return {
            "penetration": self.penetration <= MAX_PENETRATION,
            "foot_skating": not self.foot_skating > MAX_SKATING,
            "support_margin": not self.support_margin_static < MIN_SUPPORT_MARGIN,
            "contact_error": self.contact_error <= MAX_CONTACT_ERROR,
            "joint_limits": self.limit_count == 0,
            "grip_drift": self.grip_drift <= MAX_GRIP_DRIFT,
            "inside_body": self.inside_body <= MAX_INSIDE_BODY,
        }


def _reachable(result: dict[str, Any]) -> bool:
    for key in ("reachable", "success", "reached"):
        if key in result:
            return bool(result[key])
    return True


def _reaches(ir: MotionIR) -> list[tuple[str, str, float, float]]:
    """(hand, label, start, end) of each reach: TA and TO of one site, merged when contiguous."""
    out: list[tuple[str, str, float, float]] = []
    for track in ("r_arm", "l_arm"):
        segs = [s for s in ir.on_track(track) if s.kind in ("TA", "TO")]
        segs.sort(key=lambda s: s.start)
        for s in segs:
            label = f"{s.kind} {s.goal.site or ''}".strip()
            hand = s.goal.effector
            last = out[-1] if out else None
            if (
                last is not None
                and last[0] == hand
                and last[1].split(" ", 1)[-1] == (s.goal.site or "")
                and abs(last[3] - s.start) < 1e-6
            ):
                out[-1] = (hand, f"reach {s.goal.site}", last[2], s.end)
            else:
                out.append((hand, label, s.start, s.end))
    return out


def compute_metrics(ir: MotionIR) -> Metrics:
    """The metrics of the IR's output frames.

    The claims' figures (penetration, balance margin, contact error, limits, grip drift, hands
    inside the body) are read from what the verify pass measured (``ir.verification``; one
    definition, docs/metrics.md); foot skating and smoothness, which no claim rests on, are
    measured here."""
    frames = ir.frames
    skel = ir.skeleton
    if frames is None or skel is None or len(frames.time) == 0:
        raise ValueError("the IR has no frames: run the motion passes first")
    v = ir.verification
    if v is None or len(v.penetration_frames) != len(frames.time):
        raise ValueError("the IR's frames are not verified: run the verify pass last")
    t = frames.time
    # sites only: no dof axes (half the forward kinematics, a third of the pose's memory)
    # the verify pass's pose of the same frames (``output_pose``)
    pose = output_pose(skel, frames.q, frames.root_position, frames.root_rotation)
    k = int(np.argmax(v.penetration_frames))
    stance = foot_stance(ir, t)
    feet = foot_points(skel, pose)
    contact = contact_mask(feet, stance, ir.ground)
    planted = contact & ~rolling_points(ir, t)
    skate = foot_skating(feet, planted, t) if len(t) > 1 else np.full((0, 8), np.nan)
    skating = float(np.nanmax(skate)) if np.isfinite(skate).any() else math.nan
    contacts = [
        ContactError(c["effector"], c["site"], c["time"], c["error"], c["reached"], c["shortfall"])
        for c in v.contacts
    ]
    smooth: dict[str, list[tuple[str, float]]] = {}
    hands = site_positions(skel, pose, ["r_hand", "l_hand"])
    for hand, label, t0, t1 in _reaches(ir):
        inside = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
        path = hands[inside, 0 if hand.startswith("r_") else 1]
        smooth.setdefault(hand, []).append((label, ldlj(path, t[inside])))
    limits = v.limits or {}
    return Metrics(
        frames=len(t),
        duration=float(t[-1] - t[0]),
        penetration=float(v.penetration_frames[k]),
        penetration_time=float(t[k]),
        foot_skating=skating,
        support_margin=v.support_margin,
        static=v.static,
        support_margin_static=v.static_margin,
        contact_errors=contacts,
        limit_count=int(limits.get("count", 0)),
        limit_worst_deg=math.degrees(float(limits.get("excess", 0.0))),
        limit_worst_dof=str(limits.get("dof", "")),
        ldlj=smooth,
        grip_drift=max((g["drift"] for g in v.grips), default=0.0),
        inside_body=float(v.self_intersection.get("depth", 0.0)),
        penetration_by_class={k: d["depth"] for k, d in v.penetration.items()},
    )


# -- the table -------------------------------------------------------------------------------


def _fmt(v: float, scale: float, digits: int) -> str:
    return "–" if v is None or math.isnan(v) else f"{v * scale:.{digits}f}"


def metric_rows(m: Metrics) -> list[tuple[str, str, str, str]]:
    """(metric, value, threshold, verdict) rows for one motion."""
    ok = m.passes()

    def verdict(key: str) -> str:
        return "ok" if ok[key] else "FAIL"

    short = [c.shortfall for c in m.contact_errors if not c.reachable]
    reach_note = (
        f" ({len(short)} unreachable, up to {max(short) * 1e3:.0f} mm short)" if short else ""
    )
    limits = (
        f"{m.limit_count} ({m.limit_worst_deg:.2f}° {m.limit_worst_dof})" if m.limit_count else "0"
    )
    smooth = {h: [v for _, v in per if not math.isnan(v)] for h, per in m.ldlj.items()}
    ldj = ", ".join(f"{h} {min(v):.2f}" for h, v in sorted(smooth.items()) if v) or "–"
    return [
        ("frames", f"{m.frames} ({m.duration:.2f} s)", "", ""),
        ("penetration (mm)", _fmt(m.penetration, 1e3, 2), "≤ 1", verdict("penetration")),
        ("foot skating (cm/s)", _fmt(m.foot_skating, 1e2, 2), "< 2", verdict("foot_skating")),
        (
            "support margin, static (mm)",
            _fmt(m.support_margin_static, 1e3, 1),
            "≥ 0",
            verdict("support_margin"),
        ),
        (
            "contact error (mm)",
            _fmt(m.contact_error, 1e3, 2) + reach_note,
            "≤ 1",
            verdict("contact_error"),
        ),
        ("joint-limit violations", limits, "0", verdict("joint_limits")),
        ("grip drift (mm)", _fmt(m.grip_drift, 1e3, 2), "≤ 1", verdict("grip_drift")),
        ("hands inside the body (mm)", _fmt(m.inside_body, 1e3, 1), "≤ 1", verdict("inside_body")),
        ("hand smoothness, worst LDLJ", ldj, "higher is smoother", ""),
    ]


def render_metrics(runs: list[tuple[str, Metrics]]) -> str:
    """A plain-text table (rich, no colour, no terminal needed): one column per motion."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title="motion metrics", box=None, pad_edge=False)
    table.add_column("metric")
    table.add_column("threshold")
    for name, _ in runs:
        table.add_column(name, justify="right")
    per_run = [metric_rows(m) for _, m in runs]
    for i, (label, _, threshold, _) in enumerate(per_run[0] if per_run else []):
        cells = []
        for rows in per_run:
            _, value, _, verdict = rows[i]
            cells.append(f"{value} {verdict}".rstrip() if verdict == "FAIL" else value)
        table.add_row(label, threshold, *cells)
    buf = StringIO()
    console = Console(file=buf, width=200, color_system=None, force_terminal=False)
    console.print(table)
    return "\n".join(line.rstrip() for line in buf.getvalue().splitlines()) + "\n"
