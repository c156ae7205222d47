"""Pass 6: keep the centre of mass over the support polygon (seed 004, claim 4).

Claim 4 (3.4): if the projection of the body's centre of mass on the ground leaves the support
surface, adjust the root again while keeping the other joints' goals. On the dense frames:

* first, a free hand whose fingertips go under the ground turns its wrist to lift them
  (``lift_fingertips``; where it cannot, verify reports MT0512 on the output frames);
* the support polygon is the convex hull of the points that touch (``mtlc.metrics.support``:
  within 2 mm of the floor or of the site they rest on): the sole points on the feet that
  stand (both feet outside walks, the stance foot during a step: ``mtlc.metrics.foot_stance``
  reads ``result["steps"]``), kneeling knees and hands on their sites; the centre of mass
  carries what the hands hold (``mtlc.loads.carried_com``). The step records only narrow the
  support verify measures (``mtlc.metrics.touching_support``: every foot's touching points): a
  foot about to lift must not carry the correction, and a margin over fewer points is never
  larger, so what this pass balances verify finds balanced;
* in *static* frames (outside walks) whose margin is below ``MARGIN`` the pelvis moves
  horizontally until the CoM is ``MARGIN`` inside. Pushing every frame below the target margin
  (not only those outside) makes the correction grow from zero, so it is continuous in time;
* the other goals are then restored by IK, batched over the corrected frames: both legs toward
  their original foot positions and orientations (so every sole point stays put), and the arms
  of hands in contact (TO windows, and after them until the arm's next segment) toward their
  original hand positions. Where straight legs cannot follow a sideways pelvis, the pelvis
  drops by what the feet lack (the base correction's h = L − x again);
* a few such rounds converge (the legs and arms move the CoM a little too). Kneeling frames
  are balanced by the trunk alone: the pelvis would drag the knees along.

Walking frames are measured but not moved: in single support a walking body's CoM is outside
the stance foot by design (Winter 1995, "Human balance and posture control during standing and
walking", Gait & Posture 3:193: balance in gait is dynamic), and pulling it over the stance foot
would make the gait waddle. Frames that cannot be balanced with the feet and hands kept in place
keep their original pose (the contacts win) and report MT0502 once per segment, at the line of
the task that led to the segment active then.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from typing import NamedTuple

import numpy as np

from mtlc.body import (
    Pose,
    Skeleton,
    com_jacobian,
    forward,
    forward_part,
    part_site_positions,
    site_positions,
    site_rotation,
)
from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.body.ik.fast import SerialChain, solve_one
from mtlc.body.kinematics import quat_to_matrix, repeated_rows, rotate_about
from mtlc.ir.model import Frames, MotionIR, Segment, runs_of
from mtlc.loads import Held, carried_com, held
from mtlc.metrics import (
    FOOT_POINT_NAMES,
    KNEE_SLOTS,
    BoolArray,
    FloatArray,
    RestWindows,
    contact_mask,
    foot_points,
    foot_stance,
    grouped_hull,
    hand_contacts,
    hand_rest_windows,
    hull_margin,
    lowest_point,
    spans_mask,
    support,
    support_margin,
    support_push,
    swing_spans,
    walk_spans,
    walking,
)
from mtlc.passes.context import FramesPosed, PassContext
from mtlc.passes.hold import REPORT_TOL, closed_at, closed_during, last_opening, on_site
from mtlc.passes.joint_speed import speed_limited
from mtlc.passes.profile import minimum_jerk

MARGIN = 0.01  # m: how far inside the support a corrected CoM ends
ROUNDS = 6
MAX_STEP = 0.05  # m of pelvis motion per round, halved when a joint runs out of range...
MIN_STEP = 0.006  # m ...until it is this small: the pelvis then stays at its last good place
MAX_SHIFT = 0.30  # m: farther than this the posture is not a balance problem the pelvis can fix
LEG_REACH = 0.995  # of the straight leg's length: a leg is never stretched to its singularity
SEED_FLEX = 0.1  # rad: the least knee or elbow flexion IK starts from (straight is singular)
# rad: an arm resting on its site (pinned, no segment of its own live) that a correction
# leaves straighter than this, and straighter than it was, has lost its hand's contact: at
# full stretch the elbow turns as the square root of the shoulder's distance to the hand, and
# the trunk's lean peaking there bent it back 13-30 deg in a frame (issue 19)
STRAIGHT_ELBOW = math.radians(20.0)
LET_GO_TIME = 0.8  # s over which a hand resting on its site lets go as the body moves away
BODY_MOVES = ("posture", "locomotion")  # the root's segments where the whole body moves away
RESTING = 2  # a ``hands`` mask's value for a resting hand (1: pinned, 0: free)
# the legs' contact solve gives up after 4 iterations without a 10 % gain (the IK default
# waits 8): a leg that stalls is one at a joint's limit, whose error stays where it started
# (#4034: 8,700 rows a round, each 9 iterations for nothing); no row of #606, #4034 or the
# examples that the default solved failed with 4
LEG_PATIENCE = 4
POSITION_TOL = 1e-3  # m: feet and hands restored within 1 mm
BLEND_FRAMES = 6  # half-window (frames, 0.1 s at 60 fps) over which corrections blend
# s: the pelvis and trunk corrections are solved on frames this far apart (and on each run's
# last frame); the frames between take them interpolated, their contacts restored, and are
# solved in full only where that does not balance them as well as their neighbours
SOLVE_EVERY = 1 / 20
# rad/s: the fastest a correction may turn a joint (``speed_limited``); issue 19 allows
# 360 deg/s (12 deg an output frame), the kneel's own plan runs at up to 300
CORRECTED_JOINT_SPEED = math.radians(330.0)
FADE_JOINT_SPEED = math.radians(120.0)
# rad/s: an approach's arm kept on its planned path faster than this (issue 19's limit) yields
# over its TA (``too_fast``): kept there up to it, a yield costs the reach its smoothness
PERSON_JOINT_SPEED = math.radians(360.0)
DIP_SPAN = 0.5  # s each way: the most of a dip in the corrections ``jumped_corrections`` gives up
FADE_TRIES = 3  # fades toward frames given up, each giving up the frames whose fade lost contacts
CORRECTED_ROOT_SPEED = 0.3  # m/s: the fastest a pelvis correction fades where it must stop
GROUND_SLACK = 5e-4  # m a correction may take a point below the ground (half the 1 mm budget)
ACCEPT_MARGIN = 0.0  # m: what still counts as inside after correction
# the pelvis aims the CoM half a PUSH_TOL deeper than MARGIN and stops within PUSH_TOL of that
# aim: a CoM 9.5-11.5 mm inside is as balanced as one at 10 mm, and chasing the last tenth of a
# millimetre costs a round of IK on thousands of frames
PUSH_TOL = 1e-3  # m
AIM = MARGIN + PUSH_TOL / 2
COM_GAIN = 0.8  # the legs stay behind: the CoM moves ~80 % of the pelvis (measured 0.75-0.9)
FEET_SITES = ("r_foot", "l_foot")
HANDS = {"r_hand": "r_arm", "l_hand": "l_arm"}
# which segment an MT0502 is reported at when several are active: the posture that bends the
# body, then the reach that leans it, then anything else
REPORT_ORDER = {"posture": 0, "TO": 1, "TA": 2, "hold": 3, "grip": 4, "gaze": 5, "locomotion": 6}


def ends_on_site(seg: Segment) -> bool:
    """A TA segment with no approach distance (``goal both at X approach 0 cm``): no TO comes
    after it, so it is the goal's last phase and ends with the hand on the site, as a TO does.
    Left free, the pelvis's balance shift under a carried load took the hands of such a goal
    12 mm off their site (a 4 kg box held out, female P5)."""
    return seg.kind == "TA" and not seg.goal.approach


def pin_windows(
    ir: MotionIR, reached_only: bool = False
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per hand, the (lo, hi) bounds of the times it is pinned (``lo <= t < hi``), one pair per
    TO segment on its arm track, or TA segment that ends on its site (``ends_on_site``): from
    the segment's start until the next segment on that track starts, or the end of the
    motion. ``reached_only``: without the segments that left the hand short of its site
    (``distance`` over ``REPORT_TOL``, as ``hold.hold_windows``: MT0501) while its grip is
    open: such a hand neither rests on the site nor holds a part (a closed grip holds its part
    wherever the hand is, verify's MT0511)."""
    by_track: dict[str, list[Segment]] = {track: [] for track in HANDS.values()}
    grips: dict[str, list[Segment]] = {hand: [] for hand in HANDS}
    moves: list[float] = []  # where the whole body changes posture or walks
    for seg in ir.segments:  # one pass over the segments for both arms
        if seg.track in by_track:
            by_track[seg.track].append(seg)
        elif seg.track in grips and seg.kind == "grip":
            grips[seg.track].append(seg)
        elif seg.track == "root" and seg.kind in BODY_MOVES:
            moves.append(seg.start)
    moves.sort()
    out = {}
    for hand, track in HANDS.items():
        segs = sorted(by_track[track], key=lambda s: s.start)
        hand_grips = sorted(grips[hand], key=lambda s: s.start)
        starts = [s.start for s in segs]
        lo: list[float] = []
        hi: list[float] = []
        for i, seg in enumerate(segs):
            if seg.kind != "TO" and not ends_on_site(seg):
                continue
            j = bisect_left(starts, seg.end - 1e-9, lo=i + 1)  # the first later start
            end = starts[j] if j < len(starts) else math.inf
            if reached_only and float(seg.result.get("distance", 0.0)) > REPORT_TOL:
                if not closed_during(hand_grips, seg.start, end):
                    continue
                # holding its part, not resting on the site: free once it lets go (a panel
                # placed short of the floor pinned the hand there through a stand and a squat)
                end = last_opening(hand_grips, seg.start, end)
            # a hand resting on its site with its grip open lets go when the body stands up,
            # kneels or walks: kept there, a stand stretched the arm from the low filter bowl
            # and turned the shoulder 13 deg a frame (the fuel filter, female P1, issue 19)
            k = bisect_left(moves, seg.end - 1e-9)
            if k < len(moves) and moves[k] < end and not closed_at(hand_grips, moves[k]):
                end = moves[k]
            lo.append(seg.start - 1e-9)
            hi.append(end - 1e-9)
        out[hand] = (np.array(lo, dtype=float), np.array(hi, dtype=float))
    return out


def approach_windows(
    ir: MotionIR, pins: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per hand, the (lo, hi) bounds of its movements to a contact (``lo <= t < hi``): from
    the start of a TA segment on its arm track to the end of the TO that continues it, where
    one of its ``pins`` windows (``pin_windows``) starts. The pace pass planned the two as one
    movement (one velocity bell from the TA's start to the contact at the TO's end). Not the
    moves of a held part (the grip closed: two hands carrying a 4 kg cassette down from the
    ceiling had their elbows solved straight, 45 deg a frame at the TO, bench/procedures)."""
    out = {}
    for hand, track in HANDS.items():
        starts = np.sort(pins[hand][0]) if hand in pins else np.empty(0)
        segs = [s for s in ir.segments if s.track == track]
        grips = sorted((s for s in ir.segments if s.track == hand and s.kind == "grip"),
                       key=lambda s: s.start)  # fmt: skip
        lo, hi = [], []
        for seg in segs:
            if seg.kind != "TA" or ends_on_site(seg) or closed_during(grips, seg.start, seg.end):
                continue  # a held part's move is the carry pass's to re-solve
            k = np.searchsorted(starts, seg.end - 1e-6)
            if k == starts.size or abs(starts[k] - seg.end) >= 1e-6:
                continue
            to = [s for s in segs if s.kind == "TO" and abs(s.start - seg.end) < 1e-6]
            if to:
                lo.append(seg.start - 1e-9)
                hi.append(to[0].end - 1e-9)
        out[hand] = (np.array(lo, dtype=float), np.array(hi, dtype=float))
    return out


def too_fast(
    skel: Skeleton, q_before: FloatArray, q_after: FloatArray, t: FloatArray,
    approaches: dict[str, tuple[np.ndarray, np.ndarray]],
) -> dict[str, tuple[np.ndarray, np.ndarray]]:  # fmt: skip
    """The ``approaches`` (per hand, ``lo <= t < hi``) over which an arm dof of ``q_after``
    turns faster than ``PERSON_JOINT_SPEED`` where ``q_before`` did not, over two frames (an
    output frame's step at 30 fps, whichever frames the sample pass takes)."""
    out = {}
    for hand, (lows, highs) in approaches.items():
        cols = arm_dofs(skel, hand)
        step = np.abs(q_after[2:, cols] - q_after[:-2, cols])
        room = np.maximum(np.abs(q_before[2:, cols] - q_before[:-2, cols]),
                          PERSON_JOINT_SPEED * (t[2:] - t[:-2])[:, None])  # fmt: skip
        over = t[2:][(step > room + 1e-9).any(axis=1)]
        keep = [((over >= lo) & (over < hi)).any() for lo, hi in zip(lows, highs, strict=True)]
        out[hand] = (lows[keep], highs[keep])
    return out


def contacting(
    ir: MotionIR, approaches: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``approaches`` (``approach_windows``) narrowed to their TO segments: the slow end of
    the movement, where the hand must be on the path to its contact. Before it the arm's
    correction may be turned in time like any other (``arms_in_time``): kept whole over the
    TA, the corrected trunk and the re-solved arm turned an elbow 378 deg/s at the reach's
    peak (the CAD fuel filter's right hand, female P50: 12.7 deg in an output frame)."""
    out = {}
    for hand, (lows, highs) in approaches.items():
        tos = [s for s in ir.on_track(HANDS[hand]) if s.kind == "TO"]
        starts = []
        for lo, hi in zip(lows, highs, strict=True):  # the TO that ends the approach
            to = next((s for s in tos if abs(s.end - 1e-9 - hi) < 1e-6), None)
            starts.append(lo if to is None else max(lo, to.start - 1e-9))
        out[hand] = (np.array(starts, dtype=float), highs)
    return out


def departure_windows(
    ir: MotionIR,
    pins: dict[str, tuple[np.ndarray, np.ndarray]],
    approaches: dict[str, tuple[np.ndarray, np.ndarray]],
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per hand, the (lo, hi) bounds of the movements that take it off its site where one of
    its ``pins`` windows ends (``lo <= t < hi``): a TA segment on its arm track that starts
    there, but not one that starts an approach to a contact (``approach_windows``:
    ``approach_arms`` turns the arm's correction in over it from its first frame); or, where
    the body stands up, kneels or walks then (``pin_windows``), the first ``LET_GO_TIME`` of
    that."""

    def starting(segs: list[Segment]) -> tuple[FloatArray, list[Segment]]:
        segs = sorted((s for s in segs if s.end > s.start), key=lambda s: s.start)
        return np.array([s.start - 1e-9 for s in segs]), segs

    def at(starts: FloatArray, end: float) -> int | None:
        k = int(np.searchsorted(starts, end - 1e-6))
        return k if k < starts.size and abs(starts[k] - end) < 1e-6 else None

    body = starting([s for s in ir.segments if s.track == "root" and s.kind in BODY_MOVES])
    out = {}
    for hand, track in HANDS.items():
        ends = pins[hand][1] if hand in pins else np.empty(0)
        approach = np.sort(approaches[hand][0]) if hand in approaches else np.empty(0)
        # (a TA that ends on its site is pinned itself: ``ends_on_site``)
        moves = starting(
            [s for s in ir.segments if s.track == track and s.kind == "TA" and not ends_on_site(s)]
        )
        lo, hi = [], []
        for end in ends:
            if at(approach, end) is not None:
                continue
            if (k := at(moves[0], end)) is not None:
                lo.append(end)
                hi.append(moves[1][k].end - 1e-9)
            elif (k := at(body[0], end)) is not None:
                lo.append(end)
                hi.append(end + min(body[1][k].end - body[1][k].start, LET_GO_TIME))
        out[hand] = (np.array(lo, dtype=float), np.array(hi, dtype=float))
    return out


def departing_arms(
    skel: Skeleton,
    frames: Frames,
    q_start: FloatArray,
    root_start: FloatArray,
    departures: dict[str, tuple[np.ndarray, np.ndarray]],
) -> None:
    """Each arm over a movement that leaves its pinned site (``departure_windows``), in
    place, as ``approach_arms`` in reverse: the hand leaves from where its pin held it along
    the path the pace pass planned, and takes on what the corrected trunk carries it as the
    movement goes on (its minimum-jerk progress), solved by the shoulder and elbow from the pin's last correction let go in joint
    space over the movement. Let go at a person's fastest joint speed (``arms_in_time``), the
    pinned arm's correction moved the hand 27 mm in one frame at the start of a move (162 cm/s,
    the fuel filter's cartridge carried to the drain tray, male P1): a second velocity peak and
    an LDLJ of -10.7; let go in joint space alone, the hand rode on a trunk whose lean grew as
    the move began (59 cm/s in its first frame, the CAD twin; issue 19)."""
    t = frames.time
    for hand, (lows, highs) in departures.items():
        cols = arm_dofs(skel, hand)
        for lo, hi in zip(lows, highs, strict=True):
            w = np.flatnonzero((t >= lo) & (t < hi))
            if w.size == 0 or w[0] == 0:
                continue
            held = frames.q[w[0] - 1, cols] - q_start[w[0] - 1, cols]
            if not np.any(held):
                continue
            s = minimum_jerk((t[w] - lo) / max(hi - lo, 1e-9))[:, None]
            own = frames.q[np.ix_(w, cols)] - q_start[np.ix_(w, cols)]
            seed = q_start[np.ix_(w, cols)] + (1.0 - s) * held + s * own
            # where the pin held the hand off its planned path, it leaves from there
            last = [w[0] - 1]
            rot = frames.root_rotation[last]
            pinned = forward(skel, frames.q[last], frames.root_position[last], rot, with_axes=False)
            planned = forward(skel, q_start[last], root_start[last], rot, with_axes=False)
            off = site_positions(skel, pinned, hand) - site_positions(skel, planned, hand)
            arm_between(skel, frames, q_start, root_start, w, hand, seed, s, offset=(1.0 - s) * off)


def approach_arms(
    skel: Skeleton,
    frames: Frames,
    q_start: FloatArray,
    root_start: FloatArray,
    approaches: dict[str, tuple[np.ndarray, np.ndarray]],
) -> None:
    """Each arm's part in the correction, over a movement to a contact (``approach_windows``)
    planned as one movement, in place: the hand goes where the pace pass planned it, off that
    path by what the corrected trunk carries it, less and less as the movement goes on
    (1 - its minimum-jerk progress, ``profile.minimum_jerk``), and on it at the contact. The
    shoulder and elbow solve for that place, each frame from the arm's correction turned in
    over the movement in joint space (from what the arm has at its start, none mostly, to what
    the pinned hand's solve gives it at the contact); the wrist keeps that turned-in angle.

    Left as it was, a hand on its way to a contact rode on the corrected trunk (the kneeling
    fuel filter's trunk leans back up to 14 deg while the arm reaches forward: the hand
    110-125 mm off its path) and was put back on its path from the TO's first frame:
    ``arms_in_time`` let the arm take that up at a person's fastest joint speed in the last two
    or three frames of the TA, a second speed peak or an LDLJ under -8 and 13-19 deg wrist
    steps; and the whole arm solved frame by frame on the TO's path near its reach turned the
    wrist up to 19 deg a frame (female P50; issue 19). Turned in over the joints alone, the
    hand rode on the trunk until the contact and touched at 44-52 cm/s; the wrist in the solve,
    it leant on the wrist where the elbow ran straight (29 deg a frame)."""
    for hand, (lows, highs) in approaches.items():
        cols = arm_dofs(skel, hand)
        for lo, hi in zip(lows, highs, strict=True):
            w = np.flatnonzero((frames.time >= lo) & (frames.time < hi))
            end = int(np.searchsorted(frames.time, hi))
            if w.size == 0 or end >= len(frames.time):
                continue
            ridden = frames.q[w].copy()  # the corrected body with the arm as it was planned
            ridden[:, cols] = q_start[np.ix_(w, cols)]
            if not np.any(ridden != q_start[w]) and not np.any(frames.q[end] != q_start[end]):
                continue  # nothing was corrected
            first = frames.q[w[0], cols] - q_start[w[0], cols]
            at_contact = frames.q[end, cols] - q_start[end, cols]
            s = minimum_jerk((frames.time[w] - lo) / max(frames.time[end] - lo, 1e-9))[:, None]
            turned_in = q_start[np.ix_(w, cols)] + (1.0 - s) * first + s * at_contact
            # the elbow kept bent STRAIGHT_ELBOW where the contact's own solve bends it more;
            # a contact made with a straighter arm is approached as it comes (kept short
            # of it, the hand closed the gap in the contact's frame: 15 cm/s, male P1)
            at_end = float(frames.q[end, skel.dof_index(f"{hand[0]}_elbow_flex")])
            least = STRAIGHT_ELBOW if at_end >= STRAIGHT_ELBOW else 0.0
            arm_between(skel, frames, q_start, root_start, w, hand, turned_in, 1.0 - s, least)


def arm_between(
    skel: Skeleton,
    frames: Frames,
    q_start: FloatArray,
    root_start: FloatArray,
    w: np.ndarray,
    hand: str,
    seed_arm: FloatArray,
    ride: FloatArray,
    least: float = 0.0,
    offset: FloatArray | float = 0.0,
) -> None:
    """The arm of ``hand`` over the frames ``w``, in place: the hand where the pace pass planned
    it (``q_start`` on ``root_start``), off that path by ``ride`` (W, 1) of what the corrected
    trunk carries it, and by ``offset`` (W, 3), kept within the reach of the arm with its
    elbow bent ``least`` (``kept_in_reach``); the shoulder and elbow solved from ``seed_arm``
    (W, arm dofs), the wrist keeping it."""
    cols = arm_dofs(skel, hand)
    rot = frames.root_rotation[w]
    ridden = frames.q[w].copy()  # the corrected body with the arm as it was planned
    ridden[:, cols] = q_start[np.ix_(w, cols)]
    planned = site_positions(
        skel, forward(skel, q_start[w], root_start[w], rot, with_axes=False), hand
    )
    carried = site_positions(
        skel, forward(skel, ridden, frames.root_position[w], rot, with_axes=False), hand
    )
    seed = ridden
    seed[:, cols] = np.clip(seed_arm, skel.lower[cols], skel.upper[cols])
    wanted = planned + ride * (carried - planned) + offset
    wanted = kept_in_reach(skel, seed, frames.root_position[w], rot, hand, wanted, least)
    goal = [Goal(hand, position=wanted)]
    model = prepare(
        skel, goal, seed, dofs=shoulder_elbow(skel, hand),
        root_position=frames.root_position[w], root_rotation=rot,
    )  # fmt: skip
    res = solve_ta(skel, goal, seed, model=model, restarts=0, null_gain=0.0, tol=2e-4, max_iter=40)
    frames.q[np.ix_(w, cols)] = res.q[:, cols]


def kept_in_reach(
    skel: Skeleton,
    q: FloatArray,
    root_position: FloatArray,
    root_rotation: FloatArray,
    hand: str,
    goal: FloatArray,
    least: float = STRAIGHT_ELBOW,
) -> FloatArray:
    """``goal`` (N, 3) for ``hand``, brought toward its shoulder where reaching it would take
    the elbow straighter than ``least`` (rad) and than it is in ``q`` (the corrected body, the
    arm turned in from its start toward what the contact's own solve gives it, whose wrist
    the reach keeps). At full stretch the elbow turns as the square root of the
    shoulder's distance to the hand: a trunk leaning back under a reach and forward again at
    the contact bent it 0 -> 15 deg in one output frame (the kneeling fuel filter, female P50,
    issue 19). The hand stays short of its path by what the lean takes away and reaches it as
    the lean fades at the contact. The farthest reach is measured on the arm itself with its
    elbow at that bend: the shoulder's turn does not change it."""
    elbow = skel.dof_index(f"{hand[0]}_elbow_flex")
    bent = q.copy()
    bent[:, elbow] = np.minimum(q[:, elbow], least)
    pose = forward(skel, bent, root_position, root_rotation, with_axes=False)
    shoulder = pose.p[:, skel.joint_index(f"{hand[0]}_shoulder")]
    reach = np.linalg.norm(site_positions(skel, pose, hand) - shoulder, axis=1)
    away = goal - shoulder
    far = np.linalg.norm(away, axis=1)
    return shoulder + away * np.minimum(1.0, reach / np.maximum(far, 1e-12))[:, None]


def shoulder_elbow(skel: Skeleton, hand: str) -> list[int]:
    """The dofs of the shoulder and the elbow of the arm that carries ``hand``."""
    return skel.dofs_of_joints([f"{hand[0]}_shoulder", f"{hand[0]}_elbow"])


def hand_pins(
    ir: MotionIR,
    time: np.ndarray,
    windows: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> dict[str, np.ndarray]:
    """(N,) per hand: frames where the hand is on its site and must stay there.

    From the start of a TO segment until the next segment on the same arm track starts (the
    unscrewing, holding or twisting after contact), or the end of the motion. ``windows``:
    :func:`pin_windows` of ``ir``, for a caller that asks at many times.
    """
    t = np.asarray(time, dtype=float)
    if windows is None:
        windows = pin_windows(ir)
    # each window found by bisection (``metrics.spans_mask``): a mask over every frame for every
    # contact segment, once per reach, made the reach passes quadratic in the number of steps
    return {hand: spans_mask(t, lo, hi, closed=(True, False)) for hand, (lo, hi) in windows.items()}


def lower_for_reach(
    ir: MotionIR,
    q: np.ndarray,
    root_position: np.ndarray,
    root_rotation: np.ndarray,
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    pose: Pose | None = None,
) -> np.ndarray:
    """Root positions lowered where a hip is farther from its ankle's place than a leg reaches.

    A pelvis moved sideways over straight legs must drop a little (the base correction's
    h = L − x again): by what makes each hip–ankle distance at most what the leg spans now or
    ``LEG_REACH`` of its straight length, whichever is more (a straight leg that need not move
    stays as it is).
    """
    skel = ir.skeleton
    root = root_position.copy()
    if pose is None:
        pose = forward(skel, q, root_position, root_rotation)
    drop = np.zeros(len(root))
    for name, (ankle, _, touch) in feet.items():
        side = name[0]
        hip = skel.joint_index(f"{side}_hip")
        straight = sum(
            float(np.linalg.norm(skel.offsets[skel.joint_index(f"{side}_{j}")]))
            for j in ("knee", "ankle")
        )
        now = np.linalg.norm(pose.p[:, hip] - site_positions(skel, pose, name), axis=-1)
        length = np.maximum(LEG_REACH * straight, np.minimum(now, straight))
        d = pose.p[:, hip] - ankle
        flat = np.hypot(d[:, 0], d[:, 2])
        need = d[:, 1] - np.sqrt(np.maximum(length**2 - flat**2, 0.0))
        drop = np.maximum(drop, np.where(touch, need, 0.0))
    root[:, 1] -= drop
    return root


LEG_SITES = (*FEET_SITES, *(f"{side}_{p}" for side in "rl" for p in FOOT_POINT_NAMES))


def restore_contacts(
    ir: MotionIR,
    q: np.ndarray,
    root_position: np.ndarray,
    root_rotation: np.ndarray,
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    hands: dict[str, tuple[np.ndarray, np.ndarray]],
    pose: Pose | None = None,
    solve_lost: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Re-solve legs (and pinned arms) of a batch so feet and hands are where they were
    (``_restore_contacts``, unposed)."""
    q, root, worst, _ = _restore_contacts(
        ir, q, root_position, root_rotation, feet, hands, pose, solve_lost, None
    )
    return q, root, worst


def _restore_contacts(
    ir: MotionIR,
    q: np.ndarray,
    root_position: np.ndarray,
    root_rotation: np.ndarray,
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    hands: dict[str, tuple[np.ndarray, np.ndarray]],
    pose: Pose | None,
    solve_lost: bool,
    posed: bool | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Pose | None]:
    """Re-solve legs (and pinned arms) of a batch so feet and hands are where they were.

    ``feet`` maps r_foot/l_foot to target positions (B, 3), rotations (B, 3, 3) and whether the
    foot touches the ground (B,): a foot in the air keeps its joint angles instead;
    ``hands`` maps r_hand/l_hand to a row mask (B,) and target positions (B, 3); ``pose``: the
    pose of (q, root_position, root_rotation) if the caller has it (its legs are read). The
    pelvis drops by what straight legs cannot reach. Returns the new q (B, D), root positions
    and each row's worst remaining distance (m), and ``posed`` (True: with the dofs' axes,
    False: without) the whole body's pose of the result, on which the sole points are checked
    (None: only the legs are posed, the feet's chains, 9 joints of 21: a caller poses the rows
    it keeps, or ``balance_frames`` drops the rows that lost their contacts unposed).

    The pinned arms are solved first (the arms' and the legs' dofs are apart, and the legs do
    not move a hand): a row whose hand ends over ``POSITION_TOL`` off its site has lost its
    contacts whatever the legs do, and its legs are not solved (its q keeps the legs it came
    with, its error is the hand's) unless ``solve_lost`` (a caller that reads the lost rows'
    whole error). Every caller throws such rows away: on fuzz case #3198 they were 9,323 of
    14,696 rows of the pelvis's first round and every row of the trunk's.
    """
    skel = ir.skeleton
    q = q.copy()
    # a foot off the ground keeps its angles: its target is where the moved pelvis takes it
    if pose is None:  # the legs' frames (the same numbers as the whole body's pose)
        pose = forward_part(skel, q, root_position, root_rotation, LEG_SITES)
    feet = {
        name: (
            np.where(touch[:, None], pos, site_positions(skel, pose, name)),
            np.where(touch[:, None, None], rot, site_rotation(skel, pose, name)),
            touch,
        )
        for name, (pos, rot, touch) in feet.items()
    }
    # the sole points in their foot's frame as they are (a toe tip rides on the toes' joint,
    # which the legs' solve does not turn)
    soles_in_foot = {}
    for name in feet:
        soles = [f"{name[0]}_{p}" for p in FOOT_POINT_NAMES]
        rel = site_positions(skel, pose, soles) - site_positions(skel, pose, name)[:, None, :]
        soles_in_foot[name] = np.einsum("bji,bsj->bsi", site_rotation(skel, pose, name), rel)
    root = lower_for_reach(ir, q, root_position, root_rotation, feet, pose)
    moved = np.abs(root[:, 1] - root_position[:, 1]) > 1e-9
    for side in ("r", "l"):  # a straight knee is singular: start a lowered leg slightly bent
        k = skel.dof_index(f"{side}_knee_flex")
        q[moved, k] = np.maximum(q[moved, k], SEED_FLEX)
    worst = np.zeros(len(q))
    for hand, (rows, target) in hands.items():
        idx = np.flatnonzero(rows)
        if idx.size == 0:
            continue
        goal = [Goal(hand, position=target[idx])]
        elbow = skel.dof_index(f"{hand[0]}_elbow_flex")
        planned = q[idx, elbow].copy()
        q[idx, elbow] = np.maximum(q[idx, elbow], SEED_FLEX)
        model = prepare(
            skel, goal, q[idx], root_position=root[idx], root_rotation=root_rotation[idx]
        )
        res = solve_ta(
            skel, goal, q[idx], model=model, restarts=0, null_gain=0.0, tol=2e-4, max_iter=40
        )
        q[idx] = res.q
        bent = res.q[:, elbow]
        stretched = (rows[idx] == RESTING) & (bent < STRAIGHT_ELBOW) & (bent < planned - 1e-9)
        # counted as a metre off (finite: the pelvis's step schedule extrapolates errors)
        worst[idx] = np.maximum(worst[idx], np.where(stretched, 1.0, res.position_error))
    legs = np.arange(len(q)) if solve_lost else np.flatnonzero(worst <= POSITION_TOL)
    if legs.size == 0:
        return q, root, worst, _posed(skel, q, root, root_rotation, posed)
    sub = legs.size < len(q)
    ql, rl, rotl = (q[legs], root[legs], root_rotation[legs]) if sub else (q, root, root_rotation)
    goals = [
        Goal(name, position=pos[legs] if sub else pos, orientation=rot[legs] if sub else rot)
        for name, (pos, rot, _) in feet.items()
    ]
    model = prepare(skel, goals, ql, root_position=rl, root_rotation=rotl)
    res = solve_ta(
        skel, goals, ql, model=model, restarts=0, null_gain=0.0, tol=1e-4,
        orientation_tol=math.radians(0.05), max_iter=40, patience=LEG_PATIENCE,
    )  # fmt: skip
    q[legs] = res.q
    # every sole point of both feet at once, from the whole body's pose where the caller wants
    # it (the same numbers: tests/passes/test_balance_posed_soles.py)
    soles = [f"{name[0]}_{p}" for name in feet for p in FOOT_POINT_NAMES]
    out = _posed(skel, q, root, root_rotation, posed)
    if out is None:
        now_all = part_site_positions(skel, res.q, rl, rotl, soles)
    else:
        now_all = site_positions(skel, out.rows(legs) if sub else out, soles)
    for k, (pos, rot, touch) in enumerate(feet.values()):  # every sole point of a touching foot
        rel = soles_in_foot[list(feet)[k]]
        if sub:
            pos, rot, touch, rel = pos[legs], rot[legs], touch[legs], rel[legs]
        want = pos[:, None, :] + np.einsum("bij,bsj->bsi", rot, rel)
        now = now_all[:, k * len(FOOT_POINT_NAMES) : (k + 1) * len(FOOT_POINT_NAMES)]
        err = np.linalg.norm(now - want, axis=-1).max(axis=1)
        worst[legs] = np.maximum(worst[legs], np.where(touch, err, 0.0))
    return q, root, worst, out


def _posed(
    skel: Skeleton, q: np.ndarray, root: np.ndarray, rotation: np.ndarray, posed: bool | None
) -> Pose | None:
    """The pose of a ``_restore_contacts`` result: none (``posed`` None), with its dofs'
    axes (True) or without (False)."""
    if posed is None:
        return None
    return forward(skel, q, root, rotation, with_axes=posed)


def restore_contacts_posed(
    ir: MotionIR,
    q: np.ndarray,
    root_position: np.ndarray,
    root_rotation: np.ndarray,
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    hands: dict[str, tuple[np.ndarray, np.ndarray]],
    pose: Pose | None = None,
    with_axes: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Pose]:
    """``restore_contacts`` and the pose of its result (forward kinematics is the costly part
    of balancing thousands of frames: callers reuse it instead of recomputing it, and the
    feet's sole points are checked on it, not on a pose of the legs again).
    ``with_axes=False``: the pose without its dofs' axes, for a caller that needs no Jacobian
    (half the forward kinematics)."""
    q, root, worst, out = _restore_contacts(
        ir, q, root_position, root_rotation, feet, hands, pose, False, with_axes
    )
    assert out is not None
    return q, root, worst, out


def lean_trunk(
    ir: MotionIR,
    q: np.ndarray,
    root: np.ndarray,
    rot: np.ndarray,
    pts: np.ndarray,
    ok: np.ndarray,
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    hands: dict[str, tuple[np.ndarray, np.ndarray]],
    time: np.ndarray,
    holding: Held | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, Pose]:
    """Move the CoM with the trunk (lumbar and thorax) when the pelvis cannot move far enough.

    A deep squat's ankles are near their dorsiflexion limit: the pelvis cannot go forward with
    the feet flat, but the trunk can lean (flexion and lateral flexion, no twist). Damped least squares on the CoM Jacobian's horizontal
    rows over the spine dofs, then the pinned hands re-solved. Returns q, root, the worst contact
    distance, the margin and the pose. ``holding``: ``mtlc.loads.held(ir)``, if the caller has it.
    """
    skel = ir.skeleton
    if holding is None:
        holding = held(ir)
    hulls = grouped_hull(pts, ok)
    names = [f"{j}_{m}" for j in ("lumbar", "thorax") for m in ("flex", "lat")]
    spine = np.asarray([skel.dof_index(n) for n in names], dtype=np.intp)
    lo, hi = skel.lower[spine], skel.upper[spine]
    q, root = q.copy(), root.copy()
    worst = np.zeros(len(q))
    active = np.arange(len(q))
    pose = forward(skel, q, root, rot)  # every row's, kept up to date
    p = pose  # the active rows' pose, as the last round's contact solve left it
    for _ in range(ROUNDS):
        c = carried_com(ir, p, time[active], holding)[:, [0, 2]]
        push = support_push(pts[active], ok[active], c, MARGIN, hulls.take(active))
        moving = np.hypot(push[:, 0], push[:, 1]) > PUSH_TOL
        if not moving.all():
            active, push = active[moving], push[moving]
            p = p.rows(np.flatnonzero(moving))
        if active.size == 0:
            break
        # (B, 2, S), laid out as the whole Jacobian's columns were taken (batch-major last):
        # the products below see the same memory they did
        J = np.asfortranarray(com_jacobian(skel, p, dofs=spine)[:, [0, 2]])
        A = J @ np.swapaxes(J, -1, -2) + (0.02**2) * np.eye(2)
        dq = np.einsum(
            "bsk,bk->bs", np.swapaxes(J, -1, -2), np.linalg.solve(A, push[..., None])[..., 0]
        )
        big = np.abs(dq).max(axis=1, keepdims=True)
        dq *= np.minimum(1.0, 0.2 / np.maximum(big, 1e-12))  # at most ~11° a round
        qa = q[active]
        qa[:, spine] = np.clip(qa[:, spine] + dq, lo, hi)
        qa, ra, wa, p = restore_contacts_posed(
            ir, qa, root[active], rot[active], _sub_feet(feet, active), _sub_hands(hands, active)
        )
        q[active], root[active], worst[active] = qa, ra, wa
        put_pose(pose, active, p)
        # a row that lost its contacts is rejected unless a later round finds them again, which
        # none did (0 of 5,908 rows on fuzz cases #606, #4034 and the examples): it stops here
        kept = wa <= POSITION_TOL
        if not kept.all():
            active, p = active[kept], p.rows(np.flatnonzero(kept))
    margin = support_margin(pts, ok, carried_com(ir, pose, time, holding)[:, [0, 2]], hulls)
    return q, root, worst, margin, pose


def put_pose(pose: Pose, rows: np.ndarray, part: Pose) -> None:
    """Write the batched pose ``part`` into the given rows of ``pose``, in place."""
    pose.R[rows], pose.p[rows] = part.R, part.p
    pose.axes[rows], pose.root[rows] = part.axes, part.root


def _sub_feet(
    feet: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], rows: np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    return {n: (a[rows], b[rows], c[rows]) for n, (a, b, c) in feet.items()}


def _sub_hands(
    hands: dict[str, tuple[np.ndarray, np.ndarray]], rows: np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {h: (m[rows], x[rows]) for h, (m, x) in hands.items()}


def _active_segment(ir: MotionIR, t: float) -> Segment | None:
    live = [s for s in ir.segments if s.start - 1e-9 <= t <= s.end + 1e-9]
    if not live:
        return None
    return min(live, key=lambda s: (REPORT_ORDER.get(s.kind, 9), s.start))


CHUNK_FRAMES = 4096  # frames whose support is measured at once (~10 KB each while measured)


class Segments(NamedTuple):
    """What balancing reads from the segments alone (steps, contacts, pins, held loads): read
    once per ``balance_frames``, not once per run of frames and measurement (the smoothing
    pass balances hundreds of short runs, and each read walked every segment)."""

    swings: list[tuple[FloatArray, FloatArray]]
    walks: tuple[FloatArray, FloatArray]
    rests: list[RestWindows]
    pins: dict[str, tuple[np.ndarray, np.ndarray]]
    holding: Held
    approaches: dict[str, tuple[np.ndarray, np.ndarray]]
    busy: dict[str, tuple[np.ndarray, np.ndarray]]
    departures: dict[str, tuple[np.ndarray, np.ndarray]]


def read_segments(ir: MotionIR) -> Segments:
    pins = pin_windows(ir, reached_only=True)
    approaches = approach_windows(ir, pins)
    return Segments(
        swing_spans(ir),
        walk_spans(ir),
        hand_rest_windows(ir),
        pins,
        held(ir),
        approaches,
        busy_windows(ir),
        departure_windows(ir, pins, approaches),
    )


def busy_windows(ir: MotionIR) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per hand, the (lo, hi) bounds of the segments on its arm track (``lo <= t < hi``): a
    pinned hand outside them rests on its site."""
    out = {}
    for hand, track in HANDS.items():
        segs = sorted((s for s in ir.segments if s.track == track), key=lambda s: s.start)
        out[hand] = (
            np.array([s.start - 1e-9 for s in segs], dtype=float),
            np.array([s.end - 1e-9 for s in segs], dtype=float),
        )
    return out


class Measured(NamedTuple):
    """What balancing reads of frames in their original pose (``measure``): the places of the
    feet and hands, the lowest point, the sole points on the ground and the support. Kept
    for every frame (about 0.6 KB each) instead of posing the frames to correct and those the
    blend reaches a second and a third time."""

    feet: FloatArray  # (N, 2, 3) r_foot, l_foot
    feet_rotation: FloatArray  # (N, 2, 3, 3)
    hands: FloatArray  # (N, 2, 3) r_hand, l_hand
    lowest: FloatArray  # (N,) ``lowest_point``
    contact: BoolArray  # (N, 8) ``contact_mask``
    pts: FloatArray  # (N, 22, 2) ``support``
    ok: BoolArray  # (N, 22)

    @staticmethod
    def empty(n: int) -> Measured:
        return Measured(
            np.empty((n, 2, 3)), np.empty((n, 2, 3, 3)), np.empty((n, 2, 3)), np.empty(n),
            np.empty((n, 2 * len(FOOT_POINT_NAMES)), dtype=bool), np.empty((n, 22, 2)),
            np.empty((n, 22), dtype=bool),
        )  # fmt: skip

    def take(self, rows: np.ndarray) -> Measured:
        """The rows, laid out in memory as measured by themselves (``support_layout``)."""
        m = Measured(*(x[rows] for x in self))
        feet, hands = np.ascontiguousarray(m.feet), np.ascontiguousarray(m.hands)
        return m._replace(feet=feet, hands=hands, pts=support_layout(m.pts))

    def touching(self) -> BoolArray:
        """(N, 2) whether the r and l foot touch the ground (any of its sole points)."""
        return self.contact.reshape(len(self.contact), 2, -1).any(axis=2)

    def feet_goals(self) -> dict[str, tuple[FloatArray, FloatArray, BoolArray]]:
        """Each foot where it was measured: position, rotation and whether it touches, the
        ``feet`` that ``restore_contacts`` keeps."""
        touching = self.touching()
        return {
            name: (self.feet[:, k], self.feet_rotation[:, k], touching[:, k])
            for k, name in enumerate(FEET_SITES)
        }


def support_layout(pts: FloatArray) -> FloatArray:
    """``pts`` (n, 22, 2) copied into the memory layout ``mtlc.metrics.support`` gives (the
    x–z columns of (n, 22, 3) points). Sums over points (the support's centroid, its hull)
    round by layout, and a frame read from the measurements must measure to the last bit as
    it did measured by itself."""
    out = np.empty((*pts.shape[:-1], 3))[..., [0, 2]]
    out[...] = pts
    return out


def _support_state(
    ir: MotionIR,
    frames: Frames,
    idx: slice,
    stance: BoolArray,
    segs: Segments,
    into: Measured,
) -> tuple[Pose, FloatArray, FloatArray, BoolArray]:
    """Measure the frames ``idx`` into ``into``: their feet, hands and lowest point, sole
    points on the ground, support points and which bear weight (the strict support:
    ``mtlc.metrics.support``, hands within 2 mm of their site). Returns their pose, CoM (with
    the held tools and loads) and support points as ``support`` gives them."""
    skel = ir.skeleton
    t = frames.time[idx]
    q, root, rotation = frames.q[idx], frames.root_position[idx], frames.root_rotation[idx]
    # no dof axes: nothing measured or corrected from this pose needs a Jacobian (half the cost)
    pose = forward(skel, q, root, rotation, with_axes=False)
    rest = hand_contacts(ir, t, pose, segs.rests)
    # a run of frames alike in pose, stance and resting hands (a hold) is measured once: each
    # row's numbers depend on that row alone (tests/passes/test_balance_smooth_metrics.py)
    runs = repeated_rows(q, root, rotation, stance[idx], rest)
    at: slice | np.ndarray = slice(None)
    one, one_stance, one_rest = pose, stance[idx], rest
    if runs is not None:
        heads, at = runs
        one, one_stance, one_rest = pose.rows(heads), one_stance[heads], rest[heads]
    into.contact[idx] = contact_mask(foot_points(skel, one), one_stance, ir.ground)[at]
    pts, ok = support(skel, one, one_stance, ir.ground, one_rest)
    pts, ok = pts[at], ok[at]
    into.pts[idx], into.ok[idx] = pts, ok
    for k, name in enumerate(FEET_SITES):
        into.feet[idx, k] = site_positions(skel, one, name)[at]
        into.feet_rotation[idx, k] = site_rotation(skel, one, name)[at]
    for k, name in enumerate(HANDS):
        into.hands[idx, k] = site_positions(skel, one, name)[at]
    into.lowest[idx] = lowest_point(skel, one)[at]
    return pose, carried_com(ir, pose, t, segs.holding), pts, ok


class SolveGrid(NamedTuple):
    """Which rows of a batch of frames are solved (``solved``) and, for each other row, the
    solved rows around it (``before``, ``after``: positions in the batch) and its share of
    the one after (``weight``, by time)."""

    solved: BoolArray
    before: np.ndarray
    after: np.ndarray
    weight: FloatArray


def solve_grid(rows: np.ndarray, t: FloatArray, stride: int) -> SolveGrid:
    """Every ``stride``-th row of each run of consecutive frame indices ``rows`` (ascending),
    and each run's last, are solved; ``t`` (len(rows),) their times."""
    n = rows.size
    first = np.r_[True, np.diff(rows) != 1] if n else np.zeros(0, dtype=bool)
    start = np.maximum.accumulate(np.where(first, np.arange(n), 0))
    last = np.r_[first[1:], True] if n else first
    solved = ((np.arange(n) - start) % max(stride, 1) == 0) | last
    at = np.flatnonzero(solved)
    k = np.searchsorted(at, np.arange(n))  # the first solved row at or after each row
    after = at[np.minimum(k, at.size - 1)] if n else at
    before = at[np.maximum(k - 1, 0)] if n else at
    before = np.where(solved, np.arange(n), before)
    gap = t[after] - t[before]
    weight = np.where(solved, 0.0, (t - t[before]) / np.where(gap > 0, gap, 1.0))
    return SolveGrid(solved, before, after, weight)


def balance_frames(
    ir: MotionIR,
    frames: Frames,
    only: np.ndarray | None = None,
    segs: Segments | None = None,
    measured_poses: list[Pose] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Correct ``frames`` in place; returns (margin before, margin after, failed frame mask).

    ``only``: indices of the frames to look at, ascending (default all); the returned arrays
    cover them. Each run of consecutive frames is balanced by itself: the corrections are
    blended over neighbouring frames, and two frames far apart in time are no neighbours (the
    smoothing pass's frames 1.17 s and 1.87 s of the fuel filter were, and a walking frame took
    a kneeling frame's pelvis shift). ``segs``: ``read_segments(ir)``, if the caller has it.
    ``measured_poses`` (all frames only): gets the pose of every frame as measured, before
    the corrections, chunk by chunk (``forward`` without axes).
    """
    skel = ir.skeleton
    if segs is None:
        segs = read_segments(ir)
    if only is not None:
        rows = np.asarray(only, dtype=np.intp)
        if rows.size == 0:
            return np.empty(0), np.empty(0), np.zeros(0, dtype=bool)
        parts = []
        for run in np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1):
            sub = Frames(frames.fps, frames.time[run], frames.root_position[run],
                         frames.root_rotation[run], frames.q[run])  # fmt: skip
            parts.append(balance_frames(ir, sub, segs=segs))
            frames.q[run], frames.root_position[run] = sub.q, sub.root_position
        before, after, failed = (np.concatenate(x) for x in zip(*parts, strict=True))
        return before, after, failed
    t = frames.time
    q_start = frames.q.copy()
    approaching = any(lo.size for lo, _ in segs.approaches.values())
    approaching |= any(lo.size for lo, _ in segs.departures.values())
    # the root before the corrections, for ``approach_arms`` and ``departing_arms`` only (24
    # bytes a frame)
    root_start = frames.root_position.copy() if approaching else frames.root_position
    # what depends on time only, for every frame (a few booleans a frame)
    stance, static = foot_stance(ir, t, segs.swings), ~walking(ir, t, segs.walks)
    # the support and the CoM of every frame, measured a chunk of frames at a time: the poses
    # and hulls cost ~10 KB a frame, the margins kept 20 bytes (docs/passes.md, memory)
    before = np.empty(len(t))
    kneeling = np.zeros(len(t), dtype=bool)
    hopeless = np.zeros(len(t), dtype=bool)
    measured = Measured.empty(len(t))
    poses = []  # the poses of the frames to correct, chunk by chunk
    for a in range(0, len(t), CHUNK_FRAMES):
        c = slice(a, a + CHUNK_FRAMES)
        pose, com, all_pts, all_ok = _support_state(ir, frames, c, stance, segs, measured)
        if measured_poses is not None:
            measured_poses.append(pose)
        all_hull = grouped_hull(all_pts, all_ok)
        before[c] = hull_margin(all_hull, com[:, [0, 2]])
        kneeling[c] = all_ok[:, KNEE_SLOTS].any(axis=1)  # the pelvis would drag a knee along
        # a support with no inside (toes only, one edge) or a CoM farther than the pelvis may
        # move cannot be fixed here: report it without trying
        centroid = np.einsum("np,npk->nk", all_ok, all_pts) / np.maximum(all_ok.sum(1), 1)[:, None]
        hopeless[c] = ~(hull_margin(all_hull, centroid) > 0.0) | (before[c] < -MAX_SHIFT)
        low = ~np.isnan(before[c]) & (before[c] < MARGIN)
        poses.append(pose.rows(np.flatnonzero(low & static[c] & ~hopeless[c])))
        del pose, all_pts, all_ok, com, all_hull, centroid
    after = before.copy()
    failed = np.zeros(len(t), dtype=bool)
    low = ~np.isnan(before) & (before < MARGIN)
    failed[low & kneeling & (before < 0)] = True
    failed[low & hopeless & (before < 0)] = True
    failed &= static  # walking frames are measured, never moved nor reported
    # kneeling frames are balanced by the trunk alone: the pelvis would drag a knee along
    rows = np.flatnonzero(low & static & ~hopeless)
    if rows.size == 0:
        return before, after, failed
    # the frames to correct, as measured (the support stays where it was)
    pose_r, m_r = Pose.joined(poses), measured.take(rows)
    del poses
    pts, ok = m_r.pts, m_r.ok
    hulls = grouped_hull(pts, ok)
    # nothing may go deeper below the ground than it was or than GROUND_SLACK
    floor = np.minimum(m_r.lowest - 1e-4, ir.ground - GROUND_SLACK)
    touching = m_r.touching()  # (B, 2): r, l
    # a foot's orientation target is a view of the rows' pose, which the rounds below update
    # in place: a later round restores a foot to the orientation the last one left it in
    feet = {
        name: (m_r.feet[:, k], site_rotation(skel, pose_r, name), touching[:, k])
        for k, name in enumerate(FEET_SITES)
    }
    # a hand short of its site is not held there: restoring it after every correction cost
    # most of the pass (72 strokes on a site 60 m away) and lost every row it was pinned on
    pins = hand_pins(ir, t, segs.pins)
    # 1 where a hand is pinned, RESTING where no segment of its arm is live then
    busy = hand_pins(ir, t, segs.busy)
    codes = {h: pins[h] * np.where(busy[h], 1, RESTING).astype(np.int8) for h in HANDS}
    hands = {h: (codes[h][rows], m_r.hands[:, k]) for k, h in enumerate(HANDS)}
    q0 = frames.q[rows].copy()
    root0 = frames.root_position[rows].copy()
    rot = frames.root_rotation[rows]
    q, root = q0.copy(), root0.copy()
    worst = np.zeros(rows.size)
    margin = before[rows].copy()
    good = np.zeros(rows.size, dtype=bool)
    p_rows = pose_r  # the pose of (q, root), kept up to date

    def correct(sel: np.ndarray) -> None:
        """Balance the rows ``sel`` (positions in ``rows``, ascending) by the pelvis, then
        the trunk where the pelvis could not; their q, root, worst, margin and good in place."""
        # rows whose contacts gave out keep their last good pose and stop; converged rows stop
        active = sel[~kneeling[rows[sel]]]
        schedule = StepSchedule(rows.size)
        for _ in range(ROUNDS):
            c = carried_com(ir, p_rows.rows(active), t[rows][active], segs.holding)
            c = c[:, [0, 2]]
            push = support_push(pts[active], ok[active], c, AIM, hulls.take(active))
            moving = np.hypot(push[:, 0], push[:, 1]) > PUSH_TOL
            active, push = active[moving], push[moving]
            if active.size == 0:
                break
            awake = schedule.awake(active)
            trying = active[awake]
            if trying.size == 0:  # every row sits this round out
                continue
            step = schedule.steps(trying, push[awake] / COM_GAIN)
            new_root = root[trying].copy()
            new_root[:, [0, 2]] += step
            shift = new_root[:, [0, 2]] - root0[trying][:, [0, 2]]
            far = np.hypot(shift[:, 0], shift[:, 1]) > MAX_SHIFT
            # a row that went too far is lost and stops whatever its contacts do: not solved
            near = np.flatnonzero(~far)
            q_a, root_a, worst_a = q[trying].copy(), new_root, np.zeros(trying.size)
            if near.size:
                sub = trying[near]
                q_a[near], root_a[near], worst_a[near] = restore_contacts(
                    ir, q[sub], new_root[near], rot[sub], _sub_feet(feet, sub),
                    _sub_hands(hands, sub),
                )  # fmt: skip
            lost = far | ((worst_a > POSITION_TOL) & (worst[trying] <= POSITION_TOL))
            ok_rows = trying[~lost]
            q[ok_rows], root[ok_rows], worst[ok_rows] = q_a[~lost], root_a[~lost], worst_a[~lost]
            # only the rows kept are posed (a lost row keeps its pose: a squat at its ankles'
            # limit loses every row of four rounds)
            if ok_rows.size:
                moved = forward(skel, q[ok_rows], root[ok_rows], rot[ok_rows], with_axes=False)
                put_pose(p_rows, ok_rows, moved)
            retrying = schedule.update(trying, lost, far, worst_a)
            active = np.sort(np.concatenate([active[~awake], retrying]))
        p = p_rows.rows(sel)
        margin[sel] = hull_margin(
            hulls.take(sel), carried_com(ir, p, t[rows][sel], segs.holding)[:, [0, 2]]
        )
        good[sel] = (worst[sel] <= POSITION_TOL) & skel.within_limits(q[sel], tol=1e-6)
        good[sel] &= lowest_point(skel, p) >= floor[sel]
        retry = sel[~(good[sel] & (margin[sel] >= ACCEPT_MARGIN))]
        if retry.size == 0:
            return
        # second strategy: lean the trunk, from the pelvis result where it kept the contacts
        qs = np.where(good[retry, None], q[retry], q0[retry])
        rs = np.where(good[retry, None], root[retry], root0[retry])
        sub_feet, sub_hands = _sub_feet(feet, retry), _sub_hands(hands, retry)
        q2, r2, w2, m2, p2 = lean_trunk(
            ir, qs, rs, rot[retry], pts[retry], ok[retry], sub_feet, sub_hands, t[rows][retry],
            segs.holding,
        )  # fmt: skip
        ok2 = (w2 <= POSITION_TOL) & skel.within_limits(q2, tol=1e-6) & (m2 > margin[retry])
        ok2 &= lowest_point(skel, p2) >= floor[retry]
        take = retry[ok2]
        q[take], root[take], margin[take] = q2[ok2], r2[ok2], m2[ok2]
        good[take] = True

    # the frames of a grid are solved (``SOLVE_EVERY``); those between take their neighbours'
    # corrections interpolated in time, contacts restored, where that balances them as well as
    # the neighbours (the blend's own test), and are solved in full where it does not
    grid = solve_grid(rows, t[rows], round(SOLVE_EVERY * frames.fps))
    correct(np.flatnonzero(grid.solved))
    between = np.flatnonzero(~grid.solved)
    a, b = grid.before[between], grid.after[between]
    tried = between[good[a] & good[b]]
    if tried.size:
        a, b = grid.before[tried], grid.after[tried]
        w = grid.weight[tried, None]
        qi = q0[tried] + (1 - w) * (q[a] - q0[a]) + w * (q[b] - q0[b])
        ri = root0[tried] + (1 - w) * (root[a] - root0[a]) + w * (root[b] - root0[b])
        qi = np.clip(qi, skel.lower, skel.upper)
        qi, ri, wi, pi = restore_contacts_posed(
            ir, qi, ri, rot[tried], _sub_feet(feet, tried), _sub_hands(hands, tried),
            with_axes=False,
        )  # fmt: skip
        mi = hull_margin(
            hulls.take(tried), carried_com(ir, pi, t[rows][tried], segs.holding)[:, [0, 2]]
        )
        fine = (wi <= POSITION_TOL) & skel.within_limits(qi, tol=1e-6)
        fine &= lowest_point(skel, pi) >= floor[tried]
        bar = np.minimum(np.minimum(margin[a], margin[b]), MARGIN) - 1e-3
        fine &= (mi >= bar) | (mi >= MARGIN)
        took = tried[fine]
        q[took], root[took], worst[took], margin[took] = qi[fine], ri[fine], wi[fine], mi[fine]
        good[took] = True
        put_pose(p_rows, took, pi.rows(np.flatnonzero(fine)))
        between = np.setdiff1d(between, took)
    if between.size:
        correct(between)
    keep = good & (margin >= ACCEPT_MARGIN)
    # a frame keeps the best correction that kept its contacts (none: it stays as it was);
    # one still outside has lost its balance
    dq = np.zeros_like(frames.q)
    dr = np.zeros_like(frames.root_position)
    dq[rows[good]] = q[good] - q0[good]
    dr[rows[good]] = root[good] - root0[good]
    failed[rows[~keep & (before[rows] < 0)]] = True
    if not good.any():
        return before, after, failed
    # neighbouring frames corrected differently (one by the pelvis, one by the trunk, one not
    # at all) would jump: blend the corrections over a short window, then put the contacts
    # back, so that the smoothing pass finds no balance jump to undo
    size = np.abs(dq).max(axis=1) + 10.0 * np.hypot(*dr.T[[0, 2]]) + 10.0 * np.abs(dr[:, 1])
    dq, dr = blend(dq, size, BLEND_FRAMES), blend(dr, size, BLEND_FRAMES)
    dq = speed_limited(frames.q, dq, skel.lower, skel.upper, t, CORRECTED_JOINT_SPEED)
    # a neighbour's pelvis correction must not drag a knee, nor stop in one frame where the
    # knees touch down: it eases off before them (33 mm in one frame on a kneel, issue 19)
    dr = eased_off(dr, kneeling, t, CORRECTED_ROOT_SPEED)
    span = np.flatnonzero(np.abs(dq).max(axis=1) + np.abs(dr).max(axis=1) > 0)
    if span.size == 0:  # the blended corrections cancelled out: nothing to apply
        return before, after, failed
    # the frames the blend reaches, as measured in their original pose
    m_s = measured.take(span)
    pts_s, ok_s = m_s.pts, m_s.ok
    feet_b = m_s.feet_goals()
    hands_b = {h: (codes[h][span], m_s.hands[:, k]) for k, h in enumerate(HANDS)}
    floor_b = np.minimum(m_s.lowest - 1e-4, ir.ground - GROUND_SLACK)
    hull_b = grouped_hull(pts_s, ok_s)
    # a blended frame must keep its contacts and be at least as balanced as its own correction
    own = np.full(len(t), -np.inf)
    own[rows[good]] = margin[good]

    def blended(
        at: np.ndarray, share: FloatArray, no_worse: bool = False
    ) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        """The span's frames ``at`` (positions in ``span``) with ``share`` of their blended
        correction, contacts restored: q, root, margin and whether the frame keeps it: at
        least as balanced as its own correction, or as it was and inside the support, or
        (``no_worse``) as it was."""
        f = span[at]
        qs = np.clip(frames.q[f] + share[:, None] * dq[f], skel.lower, skel.upper)
        rs = frames.root_position[f] + share[:, None] * dr[f]
        sub_feet = {n: (a[at], b[at], c[at]) for n, (a, b, c) in feet_b.items()}
        sub_hands = {h: (m[at], x[at]) for h, (m, x) in hands_b.items()}
        qs, rs, ws, ps = restore_contacts_posed(
            ir, qs, rs, frames.root_rotation[f], sub_feet, sub_hands, with_axes=False
        )
        ok = (ws <= POSITION_TOL) & skel.within_limits(qs, tol=1e-6)
        ok &= lowest_point(skel, ps) >= floor_b[at]
        ms = hull_margin(hull_b.take(at), carried_com(ir, ps, t[f], segs.holding)[:, [0, 2]])
        kept = (ms >= np.minimum(own[f], MARGIN) - 1e-3) | (ms >= MARGIN)
        as_was = ms >= np.minimum(before[f], MARGIN) - 1e-3
        kept |= as_was if no_worse else as_was & (ms >= ACCEPT_MARGIN)
        return qs, rs, ms, ok & kept

    everything = np.arange(span.size)
    qb, rb, mb, fine = blended(everything, np.ones(span.size))
    # a frame that cannot take its blended correction fades it out from the nearest frame
    # that could, no faster than a person turns a joint; without this it was left as it was
    # next to a corrected one (a pinned arm 51 deg and the pelvis 33 mm in one frame, issue 19)
    share = fade_shares(t[span], fine, dq[span], dr[span])
    again = np.flatnonzero(~fine & (share > 0.0))
    if again.size:
        q2, r2, m2, ok2 = blended(again, share[again])
        took = again[ok2]
        qb[took], rb[took], mb[took], fine[took] = q2[ok2], r2[ok2], m2[ok2], True
        # a frame that took part of its correction is a dip in the lean its neighbours took
        # whole: widened into a smooth dip over them, as far as they stay inside the support
        # (one frame's 11 % less lean bent a pinned arm held straight by 18 deg, issue 19)
        taken = np.ones(span.size)
        taken[took] = share[took]
        wide = widened_dips(taken, BLEND_FRAMES)
        around = np.flatnonzero(fine & (wide < taken - 1e-9))
        if around.size:
            q3, r3, m3, ok3 = blended(around, wide[around])
            ok3 &= m3 >= ACCEPT_MARGIN
            took = around[ok3]
            qb[took], rb[took], mb[took] = q3[ok3], r3[ok3], m3[ok3]
    # ...and where a frame still cannot take any (a pinned hand out of the arm's reach once
    # the pelvis moves), its corrected neighbours fade theirs out toward it, as far as they
    # stay inside the support (a fade that would tip a frame over keeps the step). A frame
    # that had its own correction takes it (below), so they do not fade toward it: a fade
    # toward such frames, refused a frame before them, left a one-frame dip of the lean that
    # swung a pinned arm 38 deg (the fuel filter female P1's left shoulder, issue 19)
    own_good = np.zeros(len(t), dtype=bool)
    # (a frame whose own correction is none counts as bare: a kneeling reach's pinned hand
    # kept every lean from the contact's frames, and the lean stopped in one frame there)
    moved = (q != q0).any(axis=1) | (root != root0).any(axis=1)
    own_good[rows[good & moved]] = True
    bare = ~fine & ~own_good[span]
    share = fade_shares(t[span], bare, dq[span], dr[span], into=True)
    again = np.flatnonzero(fine & (share < 1.0))
    if again.size and bare.any():
        # toward a frame that lost its balance they fade even where that tips them over too:
        # kept whole, the lean stopped in one frame there (15 deg of lumbar, 28 deg of a
        # pinned shoulder, a kneeling reach, issue 19); they are reported with it (MT0502)
        q2, r2, m2, ok2 = blended(again, share[again], no_worse=True)
        took = again[ok2]
        qb[took], rb[took], mb[took] = q2[ok2], r2[ok2], m2[ok2]
    apply = span[fine]
    applied = np.concatenate(
        [qb[fine] - frames.q[apply], rb[fine] - frames.root_position[apply]], axis=1
    )
    # the root as it came, for ``given_up_where_frames_jump``: copied here, past the pass's
    # peak of memory (held from the start, its 24 bytes a frame were on top of that peak)
    root_in = root_start if approaching else frames.root_position.copy()
    frames.q[apply], frames.root_position[apply] = qb[fine], rb[fine]
    after[apply] = mb[fine]
    failed[apply] |= (mb[fine] < ACCEPT_MARGIN) & (before[apply] < 0.0) & static[apply]
    # elsewhere a frame keeps its own correction, if it had one, as far as it differs from
    # its neighbours' no faster than a person moves (``raw_shares``): kept whole, one frame's
    # own pelvis shift and arms re-solved next to frames without it made the stand's elbows
    # step 26 deg out and back (issue 19)
    raw = np.setdiff1d(rows[good], apply)
    at = np.searchsorted(rows, raw)
    frames.q[raw], frames.root_position[raw] = q[at], root[at]
    after[raw] = margin[at]
    if raw.size:
        cut, cut_margin = limit_raw(
            ir, frames, raw, q0[at], root0[at], (apply, applied), measured, codes, segs
        )
        after[cut] = np.where(np.isnan(cut_margin), before[cut], cut_margin)
        # a frame the cut leaves outside its support is reported where it was outside before
        failed[cut] |= ~(after[cut] >= ACCEPT_MARGIN) & (before[cut] < 0.0)
    # the arms re-solved frame by frame for their pinned hands, made continuous in time: the
    # correction at a contact's start turned in over its approach, then no joint faster than
    # a person's
    pinned_arms_on_branch(skel, frames, q_start, pins, measured.hands)
    departing_arms(skel, frames, q_start, root_start, segs.departures)
    held_still = pins
    if approaching:
        approach_arms(skel, frames, q_start, root_start, segs.approaches)
        moving = hand_pins(ir, t, segs.approaches)
        held_still = {hand: pins[hand] | moving[hand] for hand in pins}
    timed = arms_in_time(skel, q_start, frames.q, t, held_still)
    if approaching:
        # an approach whose arm, kept on its planned path, turns faster than a person: its
        # TA yields (``contacting``); the others stay on their paths (yielding, the kneeling
        # reach of tests/data/reach/r03 male P1 went from LDLJ -7.6 to -8.1)
        fast = too_fast(skel, q_start, timed, t, segs.approaches)
        if any(lo.size for lo, _ in fast.values()):
            narrowed = contacting(ir, fast)
            yielding = hand_pins(ir, t, fast)
            kept = hand_pins(ir, t, narrowed)
            held_still = {h: (held_still[h] & ~yielding[h]) | kept[h] for h in held_still}
            timed = arms_in_time(skel, q_start, frames.q, t, held_still)
    frames.q[:] = timed
    given_up_where_frames_jump(
        ir, frames, (q_start, root_in), codes, measured, segs, (before, after, failed), static
    )
    failed &= ~(after >= ACCEPT_MARGIN)  # blending may have balanced a frame that was not
    return before, after, failed


def arm_jumps(
    skel: Skeleton, q: FloatArray, q_start: FloatArray, t: FloatArray, pinned: BoolArray,
    hand: str,
) -> np.ndarray:  # fmt: skip
    """Frames (indices of the later frame) where ``hand``'s pinned arm turns a dof more than
    twice as fast as ``PERSON_JOINT_SPEED`` from the frame before, both pinned, where that dof
    came in (``q_start``) no faster than it: a jump between two branches of the arm that
    balancing made, not a quick turn (each such jump gives up a whole pinned run)."""
    cols = np.asarray(arm_dofs(skel, hand), dtype=np.intp)
    fast = _jumps_between(q, q_start, t, cols)
    return np.flatnonzero(fast & pinned[1:] & pinned[:-1]) + 1


def _jumps_between(
    q: FloatArray, q_start: FloatArray, t: FloatArray, cols: np.ndarray | slice
) -> BoolArray:
    """(N - 1,) whether a dof of ``cols`` steps more than twice ``PERSON_JOINT_SPEED`` from
    each frame to the next in ``q`` where it came in (``q_start``) no faster than the speed
    itself; ``CHUNK_FRAMES`` at a time (the differences of every dof of every frame were a
    third of a kilobyte a frame at the pass's peak)."""
    n = len(t)
    out = np.zeros(max(n - 1, 0), dtype=bool)
    for a in range(0, n - 1, CHUNK_FRAMES):
        b = min(a + CHUNK_FRAMES + 1, n)
        limit = PERSON_JOINT_SPEED * np.diff(t[a:b])[:, None] + 1e-9
        fast = np.abs(np.diff(q[a:b, cols], axis=0)) > 2.0 * limit
        fast &= np.abs(np.diff(q_start[a:b, cols], axis=0)) <= limit
        out[a : b - 1] = fast.any(axis=1)
    return out


def jumped_corrections(
    q: FloatArray, q_start: FloatArray, t: FloatArray, size: FloatArray
) -> BoolArray:
    """(N,) the frames whose correction to give up where any dof turns more than twice as
    fast as ``PERSON_JOINT_SPEED`` between two frames that came in no faster than it
    (``q_start``), where one of the two frames is a dip: corrected (``size``, ``_sizes``: the
    pass's measure of a correction, its largest joint plus ten times the pelvis's shift) at
    most half as much as the other. The dip's frame is given up with the run of frames
    around it (``DIP_SPAN`` each way at most) corrected no more than it; a jump between two
    corrections alike is left to the smoothing. A kneel's three frames where the knee left
    the ground took none between frames whose hips were bent 45 deg (generated procedure
    24004, female P1: 43.8 deg of hip flexion in one output frame, issue 19). Judged at the
    person's speed itself, a quick 7 deg turn gave up the corrections of a whole kneeling
    reach (tests/data/reach/r03, male P1: LDLJ -7.6 -> -8.7)."""
    n = len(t)
    out = np.zeros(n, dtype=bool)
    if n < 2:
        return out
    jumps = np.flatnonzero(_jumps_between(q, q_start, t, slice(None))) + 1
    for i in jumps:
        k, other = (i - 1, i) if size[i - 1] < size[i] else (i, i - 1)
        if size[k] > 0.5 * size[other]:
            continue
        low = (size <= size[k] + 1e-9) & (np.abs(t - t[k]) <= DIP_SPAN)
        lo, hi = k, k + 1
        while lo > 0 and low[lo - 1]:
            lo -= 1
        while hi < n and low[hi]:
            hi += 1
        out[lo:hi] = True
    return out


def given_up_where_frames_jump(
    ir: MotionIR,
    frames: Frames,
    start: tuple[FloatArray, FloatArray],
    codes: dict[str, np.ndarray],
    measured: Measured,
    segs: Segments,
    margins: tuple[FloatArray, FloatArray, BoolArray],
    static: BoolArray,
) -> None:
    """Where the corrected frames still jump, the correction is given up there, in place:
    over a hand's whole pinned run where its arm jumps between branches after
    ``pinned_arms_on_branch`` (``arm_jumps``: the hand held on its site while the trunk's
    correction moves the shoulder, no pose of the arm follows both), and over a dip in the
    corrections elsewhere (``jumped_corrections``). Those frames go back to how they came
    (``start``: q and root; a pinned arm held its site there, on one branch) and their
    neighbours fade their corrections out toward them no faster than ``fade_shares`` allows,
    contacts restored. A frame given up that was out of balance is reported (``margins``:
    before, after, failed, updated). Continuity wins over the correction: a person does not
    flip a shoulder 100 deg in a frame to stand straighter (gen_24018 of
    tests/strategies/procedures.py, pick(both, ...) then stand(): 73-105 deg of shoulder
    flexion in one frame, issue 19)."""
    skel, t = ir.skeleton, frames.time
    q_start, root_start = start
    bare = np.zeros(len(t), dtype=bool)
    for hand, code in codes.items():
        pinned = code != 0
        jumps = arm_jumps(skel, frames.q, q_start, t, pinned, hand)
        if jumps.size == 0:
            continue
        for lo, hi in runs_of(pinned):
            if ((jumps >= lo) & (jumps < hi)).any():
                bare[lo:hi] = True
    joints, pelvis = _sizes(frames.q, q_start, frames.root_position, root_start)
    bare |= jumped_corrections(frames.q, q_start, t, joints + 10.0 * pelvis)
    if not bare.any():
        return
    before, after, failed = margins
    corrected = (joints > 0.0) | (pelvis > 0.0)
    fading = fade_times(joints, pelvis)
    for attempt in range(FADE_TRIES):
        # a frame whose fade loses its contacts is given up too, and the fade starts again
        # from there (on the last try, it is given up alone): kept whole, it stepped its
        # correction next to the frames given up
        share = shares_faded(t, bare, fading, into=True)
        fade = np.flatnonzero(~bare & (share < 1.0) & corrected)
        if fade.size == 0:
            break
        dq = frames.q[fade] - q_start[fade]
        dr = frames.root_position[fade] - root_start[fade]
        qs = np.clip(q_start[fade] + share[fade, None] * dq, skel.lower, skel.upper)
        rs = root_start[fade] + share[fade, None] * dr
        m = measured.take(fade)
        hands = {h: (codes[h][fade], m.hands[:, k]) for k, h in enumerate(HANDS)}
        qs, rs, ws, ps = restore_contacts_posed(
            ir, qs, rs, frames.root_rotation[fade], m.feet_goals(), hands, with_axes=False
        )
        ok = (ws <= POSITION_TOL) & skel.within_limits(qs, tol=1e-6)
        ok &= lowest_point(skel, ps) >= np.minimum(m.lowest - 1e-4, ir.ground - GROUND_SLACK)
        bare[fade[~ok]] = True
        if not ok.all() and attempt < FADE_TRIES - 1:
            continue
        margin = hull_margin(
            grouped_hull(m.pts, m.ok), carried_com(ir, ps, t[fade], segs.holding)[:, [0, 2]]
        )
        took = fade[ok]
        frames.q[took], frames.root_position[took] = qs[ok], rs[ok]
        after[took] = margin[ok]
        # a faded frame outside its support is reported, whether or not it came in so
        failed[took] = (margin[ok] < ACCEPT_MARGIN) & static[took]
        break
    frames.q[bare], frames.root_position[bare] = q_start[bare], root_start[bare]
    after[bare] = before[bare]
    failed[bare] = (before[bare] < 0.0) & static[bare]


def _sizes(
    q: FloatArray, q_start: FloatArray, root: FloatArray, root_start: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(N,) each frame's correction: its largest joint's (rad) and the pelvis's shift (m),
    ``CHUNK_FRAMES`` at a time."""
    n = len(q)
    joints, pelvis = np.empty(n), np.empty(n)
    for a in range(0, n, CHUNK_FRAMES):
        c = slice(a, a + CHUNK_FRAMES)
        joints[c] = np.abs(q[c] - q_start[c]).max(axis=1, initial=0.0)
        pelvis[c] = np.linalg.norm(root[c] - root_start[c], axis=1)
    return joints, pelvis


def pinned_arms_on_branch(
    skel: Skeleton,
    frames: Frames,
    q_start: FloatArray,
    pins: dict[str, np.ndarray],
    hands_at: FloatArray,
) -> None:
    """Each pinned arm kept on the branch of its previous frame, in place: where its
    correction (what balancing changed of ``q_start`` on the arm's dofs) changes between two
    pinned frames faster than ``CORRECTED_JOINT_SPEED``, the later frame's arm is solved again
    for its hand's place (``hands_at`` (N, 2, 3), r_hand and l_hand) from the previous frame's
    correction, and keeps that solve if it holds the hand within ``POSITION_TOL`` with a
    smaller step; then the next frame is compared with it, and so on.

    Each frame's pinned arm is solved by itself from its own start: near a straight elbow or
    where the trunk's blended lean dips for one frame, neighbouring frames landed on different
    solutions (the fuel filter's left hand on the bowl: 38.5 deg of shoulder flexion and 20 deg
    of elbow in one frame, issue 19), which ``arms_in_time`` cannot even out: a pinned frame
    keeps its own."""
    t = frames.time
    if len(t) < 2:
        return
    limit = CORRECTED_JOINT_SPEED * np.diff(t) + 1e-9
    rotations: FloatArray | None = None  # the roots' matrices, once (a solve's own was a fifth)
    for k, hand in enumerate(HANDS):
        pinned = pins[hand]
        cols = np.asarray(arm_dofs(skel, hand), dtype=np.intp)
        corr = frames.q[:, cols] - q_start[:, cols]
        jumps = np.abs(np.diff(corr, axis=0)).max(axis=1) > limit
        jumps &= pinned[1:] & pinned[:-1]
        if not jumps.any():
            continue
        i = int(np.flatnonzero(jumps)[0]) + 1
        while i < len(t):
            if not (pinned[i] and pinned[i - 1]):
                later = np.flatnonzero(jumps[i:])  # the next jump of the frames' own
                if later.size == 0:
                    break
                i += int(later[0]) + 1
                continue
            step = np.abs(corr[i] - corr[i - 1]).max()
            if step > limit[i - 1]:
                seed = frames.q[i].copy()
                seed[cols] = np.clip(q_start[i, cols] + corr[i - 1], skel.lower[cols],
                                     skel.upper[cols])  # fmt: skip
                if rotations is None:
                    rotations = root_matrices(frames.root_rotation)
                root, rot = frames.root_position[i : i + 1], rotations[i : i + 1]
                q_arm, holds = arm_on_site(skel, hand, seed, hands_at[i, k], root, rot)
                new = q_arm[cols] - q_start[i, cols]
                if (
                    holds
                    and np.abs(new - corr[i - 1]).max() < step
                    and skel.within_limits(q_arm[None], tol=1e-6)[0]
                ):
                    frames.q[i, cols] = q_arm[cols]
                    corr[i] = new
            i += 1


def arm_on_site(
    skel: Skeleton,
    hand: str,
    seed: FloatArray,
    target: FloatArray,
    root: FloatArray,
    rotation: FloatArray,
) -> tuple[FloatArray, bool]:
    """One pose's arm solved for its hand at ``target`` from ``seed`` (D,) (the root
    ``root`` (1, 3), ``rotation`` (1, ...)): the q (D,) that ``solve_ta(..., restarts=0,
    null_gain=0.0, tol=2e-4, max_iter=40)`` returns, to the bit (the same scalar solve of
    the same chain), and whether it holds the hand within ``POSITION_TOL``.

    ``pinned_arms_on_branch`` solves thousands of single frames one after another (each
    seeded by the last): ``solve_ta``'s wrapping (the goals' arrays, the start's checks and
    the returned pose's errors posed again by the batch model) cost more than the solve, most
    of which end where they start. The solve's own error of its best pose decides, where it
    is not within 1e-9 m of ``POSITION_TOL`` (the same forward kinematics as the model's, a
    few ulps apart); there, and where the arm is no serial chain, ``solve_ta`` itself.
    """
    goal = [Goal(hand, position=target[None])]
    model = prepare(skel, goal, seed[None], root_position=root, root_rotation=rotation)
    try:
        chain = SerialChain(model)
    except ValueError:
        chain = None
    if chain is not None:
        lo, hi = model.lower, model.upper
        start = np.clip(seed[model.active], lo, hi)  # ``solve_ta``'s start, clipped
        # restarts=0: the generator is never drawn from
        qb, err, _, _ = solve_one(
            chain, target, start, lo, hi, skel.q_comfort[model.active], tol=2e-4,
            max_iter=40, restarts=0, patience=8, damping=0.02, max_error=0.25, max_step=0.5,
            null_gain=0.0, rng=_NO_DRAWS,
        )  # fmt: skip
        if abs(err - POSITION_TOL) > 1e-9:
            q = seed.copy()
            q[model.active] = qb
            return q, err <= POSITION_TOL
    res = solve_ta(skel, goal, seed[None], model=model, restarts=0, null_gain=0.0, tol=2e-4,
                   max_iter=40)  # fmt: skip
    return res.q[0], bool(res.position_error[0] <= POSITION_TOL)


def root_matrices(rotation: FloatArray) -> FloatArray:
    """Root rotations (N, 4) quaternions or (N, 3, 3) as matrices: row by row what the
    kinematics make of each row alone (``quat_to_matrix`` is elementwise but for each
    quaternion's own norm; tests/passes/test_balance_arm_on_site.py)."""
    return quat_to_matrix(rotation) if rotation.shape[-1] == 4 else rotation


_NO_DRAWS = np.random.default_rng(0)  # the generator of solves that never restart


def raw_shares(
    t: FloatArray, raw: np.ndarray, own: FloatArray, fixed: np.ndarray, given: FloatArray, d: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The corrections ``own`` (R, D + 3: joints, then pelvis) of the frames ``raw`` (indices,
    ascending), each frame's own, brought toward its neighbours': (base, excess, share) per
    raw frame, to apply as ``base + share * excess``. ``fixed`` (indices, ascending) are the
    frames whose correction is ``given`` (F, D + 3); any other frame has none. ``base`` is
    the correction interpolated in time between the nearest non-raw frames (a run with none
    on one side takes the other's), ``excess`` what the raw frame has beyond it, and
    ``share`` the part of the excess it reaches from the nearest of them at
    ``CORRECTED_JOINT_SPEED`` and ``CORRECTED_ROOT_SPEED`` (1 with no other frame)."""
    n = len(t)
    is_raw = np.zeros(n, dtype=bool)
    is_raw[raw] = True
    other = np.flatnonzero(~is_raw)
    if other.size == 0:
        return own, np.zeros_like(own), np.ones(raw.size)
    k = np.searchsorted(other, raw)
    before = other[np.clip(k - 1, 0, other.size - 1)]
    after = other[np.clip(k, 0, other.size - 1)]

    def correction(idx: np.ndarray) -> FloatArray:
        """The correction of the non-raw frames ``idx``: ``given`` or none."""
        out = np.zeros((idx.size, own.shape[1]))
        if fixed.size:
            j = np.clip(np.searchsorted(fixed, idx), 0, fixed.size - 1)
            hit = fixed[j] == idx
            out[hit] = given[j[hit]]
        return out

    c0, c1 = correction(before), correction(after)
    span = t[after] - t[before]
    w = np.where(span > 0, (t[raw] - t[before]) / np.where(span > 0, span, 1.0), 0.0)
    base = (1.0 - w)[:, None] * c0 + w[:, None] * c1
    excess = own - base
    takes = np.maximum(
        np.abs(excess[:, :d]).max(axis=1) / CORRECTED_JOINT_SPEED,
        np.linalg.norm(excess[:, d:], axis=1) / CORRECTED_ROOT_SPEED,
    )  # s the excess takes at a person's speed
    gap = np.minimum(np.abs(t[raw] - t[before]), np.abs(t[after] - t[raw]))
    return base, excess, np.clip(gap / np.maximum(takes, 1e-9), 0.0, 1.0)


def limit_raw(
    ir: MotionIR,
    frames: Frames,
    raw: np.ndarray,
    q_raw: FloatArray,
    root_raw: FloatArray,
    applied: tuple[np.ndarray, FloatArray],
    measured: Measured,
    pins: dict[str, np.ndarray],
    segs: Segments,
) -> tuple[np.ndarray, FloatArray]:
    """The frames ``raw`` (indices, ascending), which took their own correction (``frames``
    holds it; ``q_raw`` and ``root_raw`` are them before it) where a blended one lost their
    contacts, made continuous with their neighbours, in place: a raw frame's excess over the
    correction interpolated between its neighbours (``applied``: the frames that took a
    blended one and its joints and pelvis columns) is cut to what a person's joints and
    pelvis cover in the time to the nearest of them (``raw_shares``), its contacts restored.
    A frame that loses its contacts so stays as it was. Returns the frames changed and their
    margins (NaN: the frame stays as it was)."""
    skel, t, d = ir.skeleton, frames.time, ir.skeleton.n_dofs
    own = np.concatenate([frames.q[raw] - q_raw, frames.root_position[raw] - root_raw], axis=1)
    base, excess, share = raw_shares(t, raw, own, applied[0], applied[1], d)
    cut = np.flatnonzero(share < 1.0)
    if cut.size == 0:
        return raw[cut], np.empty(0)
    f = raw[cut]
    step = base[cut] + share[cut, None] * excess[cut]
    qs = np.clip(q_raw[cut] + step[:, :d], skel.lower, skel.upper)
    rs = root_raw[cut] + step[:, d:]
    m = measured.take(f)
    feet = m.feet_goals()
    hands = {h: (pins[h][f], m.hands[:, k]) for k, h in enumerate(HANDS)}
    qs, rs, ws, ps = restore_contacts_posed(
        ir, qs, rs, frames.root_rotation[f], feet, hands, with_axes=False
    )
    ok = (ws <= POSITION_TOL) & skel.within_limits(qs, tol=1e-6)
    ok &= lowest_point(skel, ps) >= np.minimum(m.lowest - 1e-4, ir.ground - GROUND_SLACK)
    margin = hull_margin(
        grouped_hull(m.pts, m.ok), carried_com(ir, ps, t[f], segs.holding)[:, [0, 2]]
    )
    frames.q[f] = np.where(ok[:, None], qs, q_raw[cut])
    frames.root_position[f] = np.where(ok[:, None], rs, root_raw[cut])
    return f, np.where(ok, margin, np.nan)


class StepSchedule:
    """The pelvis step of each row of ``balance_frames``: at most ``MAX_STEP`` a round, halved
    after a round that lost the row's contacts (a joint ran out of range) down to ``MIN_STEP``.

    A lost row keeps its pose, so its next try moves the pelvis the same way, only less far. The
    retries that cannot succeed are skipped (on the pelvis rounds of fuzz case #4034, 8,700
    rows a round lost every retry at an ankle's limit, 0.7 s of IK a round):

    * a retry whose cap is still at least the step the row asked for would solve the same
      problem again and lose again: the row sits that round out (``awake``) with its cap
      halved, as if it had lost it, and stops once the cap is under ``MIN_STEP``;
    * a row that lost two steps running stops when the contact error, extrapolated along the
      secant through those two losses to the smallest step its halvings would try, is still
      over ``POSITION_TOL``. Beyond a joint's limit the error grows with the step (26, 12.3,
      6.2, 3.1 mm at 50, 25, 12.5, 6.25 mm on #4034: convex, ``k·max(s − slack, 0)``), and a
      convex function lies above its secant outside the chord: every retry would lose.
    """

    def __init__(self, n: int) -> None:
        self.cap = np.full(n, MAX_STEP)
        self.wanted = np.zeros(n)  # the step a row's CoM asked for last (m)
        self.asleep = np.zeros(n, dtype=np.intp)  # rounds a row sits out before its next try
        self.size = np.zeros(n)  # the step a row tried last (m), within its cap
        self.lost_size = np.zeros(n)  # the step and contact error of its last loss...
        self.lost_error = np.zeros(n)  # ...(0 once a step kept the contacts)

    def awake(self, active: np.ndarray) -> np.ndarray:
        """Which of the ``active`` rows (mask) try a step this round; the others sit it out."""
        resting = self.asleep[active] > 0
        self.asleep[active[resting]] -= 1
        return ~resting

    def steps(self, active: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """The ground-plane steps (B, 2) of the ``active`` rows: ``wanted`` cut to their cap."""
        size = np.hypot(wanted[:, 0], wanted[:, 1])
        step = wanted * np.minimum(1.0, self.cap[active] / np.maximum(size, 1e-12))[:, None]
        self.wanted[active] = size
        self.size[active] = np.minimum(size, self.cap[active])
        return step

    def update(
        self, active: np.ndarray, lost: np.ndarray, far: np.ndarray, error: np.ndarray
    ) -> np.ndarray:
        """The rows of ``active`` that try again: ``lost`` (B,) rows halve their cap (once more
        for each round whose retry would repeat the lost step) and stop when it falls under
        ``MIN_STEP`` or when no retry can keep the contacts (``error``: the round's contact
        error, m); rows that went ``far`` stop."""
        rows, cap = active[lost], self.cap[active[lost]] / 2
        wanted, asleep = self.wanted[rows], np.zeros(rows.size, dtype=np.intp)
        repeat = (wanted <= cap) & (cap >= MIN_STEP)
        while repeat.any():
            asleep += repeat
            cap = np.where(repeat, cap / 2, cap)
            repeat = (wanted <= cap) & (cap >= MIN_STEP)
        # the error at the smallest step the halvings try, on the secant of the last two losses
        size, err = self.size[rows], error[lost]
        prev_size, prev_err = self.lost_size[rows], self.lost_error[rows]
        chord = prev_size > size
        smallest = cap / 2.0 ** np.floor(np.log2(np.maximum(cap, MIN_STEP) / MIN_STEP))
        slope = (prev_err - err) / np.where(chord, prev_size - size, 1.0)
        hopeless = chord & (err + slope * (np.minimum(wanted, smallest) - size) > POSITION_TOL)
        self.cap[rows] = np.where(hopeless, 0.0, cap)
        self.asleep[rows] = asleep
        self.lost_size[rows], self.lost_error[rows] = size, err
        kept = active[~lost]
        self.lost_size[kept], self.lost_error[kept] = 0.0, 0.0
        return active[(self.cap[active] >= MIN_STEP) & ~far]


ARM_JOINTS = ("clavicle", "shoulder", "elbow", "wrist")


def arm_dofs(skel: Skeleton, hand: str) -> list[int]:
    """The dofs of the arm that carries ``hand`` (r_hand: r_clavicle to r_wrist)."""
    return skel.dofs_of_joints([f"{hand[0]}_{j}" for j in ARM_JOINTS])


def arms_in_time(
    skel: Skeleton,
    q_before: FloatArray,
    q_after: FloatArray,
    t: FloatArray,
    held: dict[str, np.ndarray],
) -> FloatArray:
    """``q_after`` with each arm's correction (what a pass changed of ``q_before`` on that
    arm's dofs) turned no faster than ``CORRECTED_JOINT_SPEED``: where it would be faster (a
    hand re-solved on its site from its pin's first frame, the frame before left as it was),
    the correction starts earlier and lets go later in the frames where the hand is free;
    frames in ``held[hand]`` (N,) keep their own, so a pinned hand stays on its goal.

    The passes that re-solve a pinned arm frame by frame after interpolation (balance,
    smoothing) made the output's largest one-frame steps: 51 deg of wrist flexion where the
    fuel filter's reach became a contact (male P1), 108 deg of shoulder rotation at a squat's
    start (issue 19). The arm's solve is per frame; its continuity in time is restored here."""
    out = q_after.copy()
    for hand, mask in held.items():
        cols = arm_dofs(skel, hand)
        before = q_before[:, cols]
        delta = speed_limited(before, q_after[:, cols] - before, skel.lower[cols],
                              skel.upper[cols], t, CORRECTED_JOINT_SPEED, fixed=mask)  # fmt: skip
        out[:, cols] = before + delta
    return out


def fade_shares(
    t: FloatArray, kept: BoolArray, dq: FloatArray, dr: FloatArray, into: bool = False
) -> FloatArray:
    """(N,) the share of its correction each frame of a run takes: 1 where ``kept``, and
    elsewhere what is left of the nearest kept frame's correction after fading it for the time
    between them at ``FADE_JOINT_SPEED`` (joints, ``dq``) and ``CORRECTED_ROOT_SPEED``
    (pelvis, ``dr``), whichever takes longer; 0 with no kept frame. ``into``: the other way,
    ``kept`` are the frames that take none, and each other frame's own correction fades to
    nothing at the nearest of them (1 with none)."""
    return shares_faded(
        t, kept, fade_times(np.abs(dq).max(axis=1), np.linalg.norm(dr, axis=1)), into
    )


def fade_times(joints: FloatArray, pelvis: FloatArray) -> FloatArray:
    """(N,) s each frame's correction takes to fade: its largest joint's (rad) at
    ``FADE_JOINT_SPEED`` or its pelvis shift (m) at ``CORRECTED_ROOT_SPEED``, the longer."""
    return np.maximum(joints / FADE_JOINT_SPEED, pelvis / CORRECTED_ROOT_SPEED)


def shares_faded(t: FloatArray, kept: BoolArray, size: FloatArray, into: bool) -> FloatArray:
    """``fade_shares`` of corrections that take ``size`` (N,) s to fade (``fade_times``)."""
    if into:
        if not kept.any():
            return np.ones(len(t))
        idx = np.flatnonzero(kept)
        k = np.searchsorted(idx, np.arange(len(t)))
        gap = np.minimum(
            np.abs(t - t[idx[np.clip(k - 1, 0, idx.size - 1)]]),
            np.abs(t[idx[np.clip(k, 0, idx.size - 1)]] - t),
        )
        return np.clip(gap / np.maximum(size, 1e-9), 0.0, 1.0)
    if not kept.any():
        return np.zeros(len(t))
    idx = np.flatnonzero(kept)
    k = np.searchsorted(idx, np.arange(len(t)))
    share = np.zeros(len(t))
    for near in (idx[np.clip(k - 1, 0, idx.size - 1)], idx[np.clip(k, 0, idx.size - 1)]):
        gap = np.abs(t - t[near])
        share = np.maximum(share, 1.0 - gap / np.maximum(size[near], 1e-9))
    share[kept] = 1.0
    return np.clip(share, 0.0, 1.0)


def widened_dips(share: FloatArray, half: int) -> FloatArray:
    """``share`` (N,) with each dip under 1 widened into its neighbours: the smallest share
    within ``half`` frames, averaged over 2·half + 1 frames (never more than the share
    itself; 1 where no dip is within 2·half frames)."""
    pad = np.concatenate([np.ones(half), share, np.ones(half)])
    low = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1).min(axis=1)
    pad = np.concatenate([np.ones(half), low, np.ones(half)])
    mean = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1).mean(axis=1)
    return np.minimum(share, mean)


def eased_off(delta: FloatArray, zero: BoolArray, t: FloatArray, speed: float) -> FloatArray:
    """``delta`` (N, K) zero at the ``zero`` frames and, around them, no larger than ``speed``
    times the time to the nearest such frame: a correction that must vanish there fades out
    at that speed instead of stopping from one frame to the next."""
    if not zero.any():
        return delta
    at = t[zero]
    k = np.searchsorted(at, t)
    gap = np.minimum(
        np.abs(t - at[np.clip(k - 1, 0, at.size - 1)]), np.abs(at[np.clip(k, 0, at.size - 1)] - t)
    )
    return np.clip(delta, -(speed * gap)[:, None], (speed * gap)[:, None])


def blend(delta: np.ndarray, norm: np.ndarray, half: int) -> np.ndarray:
    """Per-frame corrections made continuous: dilated, then averaged over 2·half + 1 frames.

    Each frame first takes the largest correction (by ``norm``) within ``half`` frames, then a
    centred moving average smooths the steps. A frame that needed a correction keeps it in
    full when its neighbours needed about as much, and the correction starts ``half`` to
    2·half frames before it is needed (an anticipatory adjustment) instead of jumping in.
    """
    n = len(delta)
    pad = np.concatenate([np.full(half, -1.0), norm, np.full(half, -1.0)])
    windows = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    src = np.clip(np.arange(n) + windows.argmax(axis=1) - half, 0, n - 1)
    dilated = delta[src]
    c = np.cumsum(np.concatenate([np.zeros((1, *delta.shape[1:])), dilated]), axis=0)
    idx = np.arange(n)
    hi, lo = np.minimum(idx + half + 1, n), np.maximum(idx - half, 0)
    return (c[hi] - c[lo]) / (hi - lo).reshape(-1, *([1] * (delta.ndim - 1)))


def _mm(metres: float) -> str:
    """Millimetres to print: whole from 1 cm, tenths from 1 mm, hundredths below (a shortfall
    of 0.04 mm does not read "0.0 mm")."""
    mm = metres * 1000
    if mm >= 9.5:
        return f"{mm:.0f}"
    return f"{mm:.1f}" if mm >= 0.95 else f"{mm:.2f}"


def failure_runs(failed: np.ndarray, gap: int = 6) -> list[tuple[int, int]]:
    """(first, last) frame of each run of failed frames; runs closer than ``gap`` merge."""
    idx = np.flatnonzero(failed)
    if idx.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(idx) > gap)
    firsts = np.r_[idx[0], idx[cuts + 1]]
    lasts = np.r_[idx[cuts], idx[-1]]
    return list(zip(firsts.tolist(), lasts.tolist(), strict=True))


TIP_SITES = {"r": "r_fingertip", "l": "l_fingertip"}
TIP_CLEAR = 0.005  # m: a lifted fingertip ends this far above the ground
WRIST_GRID = 41  # wrist flexion values tried per frame
TIP_BLEND = 15  # half-window (frames, 0.25 s at 60 fps): a wrist turns in over half a second


def lift_fingertips(ir: MotionIR, frames: Frames) -> dict[str, np.ndarray]:
    """Flex the wrist of a free hand whose fingertip goes under the ground, in place.

    A hand swung low on its way to a site (a TA path past the floor) can take its fingertips,
    18 cm beyond the wrist, through the floor while the hand itself stays above it. Each run of
    such frames where the hand is not on a site (``hold.on_site``: a hand that let go is free,
    though ``hand_pins`` keeps it pinned until its arm's next segment) turns the wrist one way, the one
    that needs the least flexion to lift every frame's fingertip ``TIP_CLEAR`` above the
    ground; the corrections are blended over ``TIP_BLEND`` frames so nothing jumps, never touch a
    pinned frame (a hand on its site stays on it), and are repeated while they help. Returns,
    per side, the depth (m, positive under the ground) of its fingertip at each frame.
    """
    skel = ir.skeleton
    t = frames.time
    pins = on_site(ir, t)
    out: dict[str, np.ndarray] = {}
    start = np.empty((len(t), len(TIP_SITES)))  # one FK of the frames for both sides
    for a in range(0, len(t), CHUNK_FRAMES):
        c = slice(a, a + CHUNK_FRAMES)
        tips = part_site_positions(skel, frames.q[c], frames.root_position[c],
                                   frames.root_rotation[c], list(TIP_SITES.values()))  # fmt: skip
        start[c] = ir.ground - tips[..., 1]
    for i, (side, tip) in enumerate(TIP_SITES.items()):
        depth = start[:, i].copy()  # a side's wrist does not move the other side's fingertip
        free = ~pins[f"{side}_hand"]
        k = skel.dof_index(f"{side}_wrist_flex")
        wrist0 = frames.q[:, k].copy()
        grid = np.linspace(skel.lower[k], skel.upper[k], WRIST_GRID)
        for _ in range(3):
            low = (depth > -TIP_CLEAR + 1e-4) & free
            if not low.any():
                break
            delta = np.zeros((len(t), 1))
            for first, last in failure_runs(low, BLEND_FRAMES):
                rows = np.arange(first, last + 1)
                rows = rows[free[rows]]
                # a later round turns a run the way an earlier one did (the other way, the
                # frames it did not clear flipped 146 deg, issue 19)
                done = float(np.sum(frames.q[rows, k] - wrist0[rows]))
                ways = (1.0, -1.0) if done == 0.0 else (math.copysign(1.0, done),)
                delta[rows, 0] = _wrist_lift(ir, frames, rows, k, grid, tip, ways)
            delta = blend(delta, np.abs(delta[:, 0]), TIP_BLEND)
            delta[~free] = 0.0  # a hand on its site keeps its wrist
            moved = np.flatnonzero(delta[:, 0] != 0.0)
            if moved.size == 0:
                break
            q_new = np.clip(frames.q[moved, k] + delta[moved, 0], skel.lower[k], skel.upper[k])
            q = frames.q[moved].copy()
            q[:, k] = q_new
            new_depth = (
                ir.ground
                - part_site_positions(
                    skel, q, frames.root_position[moved], frames.root_rotation[moved], [tip]
                )[:, 0, 1]
            )
            # a frame takes the change where it does not take the fingertip deeper
            take = new_depth <= np.maximum(depth[moved], 0.0) + 1e-6
            frames.q[moved[take], k] = q_new[take]
            depth[moved[take]] = new_depth[take]
        out[side] = depth
    return out


def _wrist_lift(
    ir: MotionIR,
    frames: Frames,
    rows: np.ndarray,
    k: int,
    grid: np.ndarray,
    tip: str,
    ways: tuple[float, ...] = (1.0, -1.0),
) -> np.ndarray:
    """The wrist flexion change (rows,) that clears the fingertip of a run of frames, all one
    way: of flexing and extending (``ways``: those allowed), the one whose largest change is
    the least (where neither clears every frame, the one whose lowest frame comes highest)."""
    change = grid[None, :] - frames.q[rows, k][:, None]
    height = tip_heights(ir.skeleton, frames, rows, k, change, tip)
    clear = height >= ir.ground + TIP_CLEAR
    best, best_cost = None, np.inf
    for sign in ways:
        ok = clear & (sign * change >= 0.0)
        if not ok.any(axis=1).all():
            continue
        pick = np.argmin(np.where(ok, np.abs(change), np.inf), axis=1)
        cost = float(np.abs(change[np.arange(rows.size), pick]).max())
        if cost < best_cost:
            best, best_cost = pick, cost
    if best is None:
        # neither way clears every frame: the way whose lowest frame comes highest, each frame
        # at its highest that way (each frame's own best way flipped the wrist 150 deg from one
        # frame to the next in a squat, issue 19)
        best_low = -np.inf
        for sign in ways:
            way = np.where(sign * change >= 0.0, height, -np.inf)
            pick = np.argmax(way, axis=1)
            low = float(way[np.arange(rows.size), pick].min())
            if best is None or low > best_low:
                best, best_low = pick, low
    assert best is not None
    return change[np.arange(rows.size), best]


def tip_heights(
    skel: Skeleton, frames: Frames, rows: np.ndarray, k: int, change: np.ndarray, tip: str
) -> np.ndarray:
    """Height (rows, n) of site ``tip`` with dof ``k`` of each row turned by each ``change``.

    One forward kinematics of the rows, not one per change: turning dof ``k`` by Δ turns
    everything beyond its joint about the dof's world axis through the joint, so the site is the
    joint plus the joint-to-site vector rotated by Δ (Rodrigues). A run the length of a task
    took a whole-body FK of rows × 41 postures before: seconds for a long one."""
    pose = forward(skel, frames.q[rows], frames.root_position[rows], frames.root_rotation[rows])
    joint = pose.p[:, skel.dof_joint[k]]  # (rows, 3): a joint's place is not moved by its dofs
    u = site_positions(skel, pose, tip) - joint
    a = pose.axes[:, k]  # (rows, 3), unit
    turns = np.asarray(change)[..., None]  # (n, 1) against the points' (rows, 1, 3)
    tips = rotate_about(joint[:, None], a[:, None], u[:, None], np.cos(turns), np.sin(turns))
    return tips[..., 1]


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    frames = ir.frames
    if frames is None or ir.skeleton is None or len(frames.time) == 0:
        return ir
    lift_fingertips(ir, frames)  # what stays under the floor is verify's MT0512
    # the pose of every frame, handed on to smoothing, clearance and verify (up to
    # ``FramesPosed.MAX_FRAMES``: 1.8 KB a frame, 100 MB at the default motion budget)
    measured = FramesPosed.of(frames, []) if len(frames.time) <= FramesPosed.MAX_FRAMES else None
    poses = None if measured is None else measured.poses
    _, after, failed = balance_frames(ir, frames, measured_poses=poses)
    if measured is not None:
        ctx.cache[FramesPosed.KEY] = measured
    t = frames.time
    reported: set[int] = set()
    for first, last in failure_runs(failed):
        seg = _active_segment(ir, float(t[first]))
        if seg is None or id(seg) in reported:
            continue
        reported.add(id(seg))
        run_failed = failed[first : last + 1]
        worst = float(np.nanmin(after[first : last + 1][run_failed]))
        when = (
            f"at {t[first]:.2f} s" if last == first else f"from {t[first]:.2f} s to {t[last]:.2f} s"
        )
        ctx.report(
            "MT0502",
            f"the manikin loses its balance in `{' > '.join(seg.provenance.path)}`: {when} the "
            f"centre of mass is up to {_mm(-worst)} mm outside the support, and moving "
            "the pelvis cannot bring it back with the feet and hands in place",
            seg.provenance.origin,
        )
    return ir
