"""Verify, the last pass: every claim the compiler makes, checked on the frames a user receives.

The other passes aim at these claims; this pass measures them on the sampled output frames (the
frames the generators write, at the output rate) and reports each failure at the task line that
asked for it. What it measures is stored on the IR (``MotionIR.verification``) so that metrics,
lint, report and preview read one figure instead of measuring it again (docs/metrics.md defines
each figure once; ARCHITECTURE.md, "One home for each truth"):

* contact: each goal's effector (hand or tool tip) on its site at the first output frame at or
  after the goal's end (MT0510 when the solver said it reached it; a goal the solver could not
  reach is MT0501, with the shortfall measured here: the distance from the site to the closest
  point the effector comes to over the goal's frames);
* grips: a closed hand on a part does not move while nothing moves it (MT0511);
* the floor: no joint centre, sole point, hand, fingertip or tool tip below it (MT0512);
* joint limits (MT0513);
* static balance: the centre of mass (with what the hands hold) over the support of the points
  that touch (MT0502, measured here; the balance pass's own estimate is not reported);
* hands and forearms outside the trunk and the thighs (``mtlc.body.capsules``; MT0514);
* the body and its held tools outside the equipment: every collision capsule against every
  scene model's mesh (``mtlc.geometry.clearance``), deeper than ``EQUIPMENT_TOLERANCE`` is a
  finding (MT0515), except a hand or its tool touching the model at its goal's site.

Every finding is a warning: the frames are written and usable, and the finding is about the
motion, like MT0501 and MT0502 (docs/metrics.md, "Verification"). Figures are vectorised over
frames (one forward kinematics of the output frames).
"""

from __future__ import annotations

import math
import time as clock
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from mtlc.body import site_positions
from mtlc.body.capsules import capsule_segments, collision_capsules, self_intersection
from mtlc.body.kinematics import Pose, output_pose, repeated_rows
from mtlc.geometry.clearance import FrameClearance, frame_clearance, held_capsules, scene_pieces
from mtlc.geometry.held import HeldPart, held_parts
from mtlc.ir.model import FloatArray, MotionIR, Segment, SourceRef, Verification
from mtlc.metrics import balance_margin, walking
from mtlc.passes.approach import effector_name
from mtlc.passes.balance import CHUNK_FRAMES, _mm, failure_runs
from mtlc.passes.context import FramesPosed, PassContext
from mtlc.passes.hold import carried_postures
from mtlc.passes.tool import is_stroke

TOLERANCE = 1e-3  # m: contact error, grip drift, depth below the floor, depth inside the body
# m: a stretch inside is reported at each line live where it is this near its deepest
NEAR_DEEPEST = 2e-3
# m a capsule may go into a model unreported: the capsules are round and the hands bare, so a
# few millimetres is a sleeve brushing a panel, not a limb inside it (docs/collision.md)
EQUIPMENT_TOLERANCE = 5e-3
# m: an effector this close to its goal's site is at the site (the hand or tool touches what it
# works on), and a model this close to a site is one the site is on
CONTACT_ZONE = 0.05
LIMIT_TOLERANCE = 1e-6  # rad past a joint's limit (rounding, not motion)
MIN_MARGIN = 0.0  # m: the centre of mass inside the support
EPS = 1e-9
# a pelvis above this fraction of its standing height is standing (a squat or kneel is lower)
STANDING_PELVIS = 0.85

HAND_NAMES = {"r": "right hand", "l": "left hand"}
ARM_TRACK = {"r": "r_arm", "l": "l_arm"}
HAND_TRACK = {"r": "r_hand", "l": "l_hand"}
# which active segment a finding is reported at, when no track is preferred: the posture that
# shapes the body, then the reach that leans it, then anything else (as the balance pass)
REPORT_ORDER = {"posture": 0, "TO": 1, "TA": 2, "hold": 3, "grip": 4, "locomotion": 5, "gaze": 6}
POINT_CLASSES = ("joints", "soles", "hands", "fingertips", "tool tips")
SOLE_SITES = tuple(f"{s}_{p}" for s in ("r", "l") for p in ("heel", "toe", "ball_med", "ball_lat"))


def _reachable(result: dict[str, Any]) -> bool:
    """The solver's verdict on a goal (``reachable``, ``success`` or ``reached``)."""
    return all(bool(result[key]) for key in ("reachable", "success", "reached") if key in result)


# m: depths are compared at this resolution when picking the deepest frame. A hand resting in a
# model or a sole on the floor is equally deep on every frame of the rest to the last bits, and
# those bits differ between machines (BLAS builds): the first frame of the plateau is the one.
DEPTH_RESOLUTION = 1e-4


def _noise_free(depth: float) -> float:
    return round(depth / DEPTH_RESOLUTION) if math.isfinite(depth) else depth


def deepest(depth: FloatArray) -> int:
    """Index of the deepest frame, the first of those equal at ``DEPTH_RESOLUTION``."""
    return int(np.argmax(np.round(depth / DEPTH_RESOLUTION)))


def point_name(name: str) -> str:
    """How a message names a body point: "the left fingertip", "the right ball med", "the tip of
    wrench_10mm in the right hand"."""
    side, _, rest = name.partition("_")
    if rest.startswith("tool_"):
        return f"the tip of {effector_name(name)}"
    if side in ("r", "l"):
        return f"the {'right' if side == 'r' else 'left'} {rest.replace('_', ' ')}"
    return f"the {name.replace('_', ' ')}"


class _Verifier:
    """One verification: the frames, their poses and what has been found."""

    def __init__(self, ir: MotionIR, ctx: PassContext) -> None:
        assert ir.frames is not None and ir.skeleton is not None
        self.ir, self.ctx, self.skel = ir, ctx, ir.skeleton
        f = ir.frames
        self.t: FloatArray = np.asarray(f.time, dtype=float)
        # no Jacobian is taken here: the dof axes (a third of the pose's memory) are left out
        # the passes' pose of these frames, brought up to date (clearance's, via sample)
        handed = FramesPosed.take(ctx.cache, f)
        posed = None if handed is None else handed.all_now(self.skel, f)
        self.pose: Pose = output_pose(
            self.skel, f.q, f.root_position, f.root_rotation, keep=True, posed=posed
        )
        self.v = Verification()
        self.reported: set[tuple[Any, ...]] = set()
        self.claims = [c for c in ctx.claims]
        ctx.claims.clear()
        self.segs = sorted(ir.segments, key=lambda s: (s.start, s.end))
        self.paths: dict[str, FloatArray] = {}
        # per side: the site of the two-handed goal held at each frame, and the closed grips
        self.held: dict[str, tuple[Any, list[tuple[float, float, Segment]]]] = {}
        self.short: dict[tuple[SourceRef, str | None, str], tuple[float, float]] = {}
        # a wrench's strokes: the worst tip distance where a stroke the solver left short ends
        self.stroke_short: dict[tuple[SourceRef, str | None, str], tuple[float, float]] = {}

    # -- reporting ---------------------------------------------------------------------------

    def report(
        self, code: str, message: str, ref: SourceRef, key: Any = None, help: str | None = None
    ) -> None:
        """One finding, once per ``key`` (default: code, line and message)."""
        k = (code, ref, message) if key is None else (code, ref, key)
        if k in self.reported:
            return
        self.reported.add(k)
        self.ctx.emit(code, message, ref, help=help)
        self.v.findings.append(
            {"code": code, "message": message, "line": ref.line, "column": ref.column}
        )

    def frame_at(self, time: float) -> int:
        """The first output frame at or after ``time`` (the last frame past the end)."""
        return min(int(np.searchsorted(self.t, time - EPS)), len(self.t) - 1)

    def active(self, i: int, tracks: Iterable[str] = ()) -> Segment | None:
        """The segment a finding at frame ``i`` is reported at: one on ``tracks`` if any is
        live, else by ``REPORT_ORDER``; between segments the last one that ended."""
        t = float(self.t[i])
        live = [s for s in self.segs if s.start - EPS <= t <= s.end + EPS]
        if not live:
            ended = [s for s in self.segs if s.end <= t + EPS]
            live = ended[-1:] or self.segs[:1]
        if not live:
            return None
        pref = set(tracks)
        return min(
            live,
            key=lambda s: (s.track not in pref, REPORT_ORDER.get(s.kind, 9), s.end - s.start),
        )

    def posture_at(self, i: int) -> Segment | None:
        """The whole-body posture live at frame ``i`` (it moves every point of the body)."""
        t = float(self.t[i])
        live = [s for s in self.ir.on_track("root") if s.kind == "posture"]
        return next((s for s in live if s.start - EPS <= t <= s.end + EPS), None)

    def last_on(self, track: str, i: int) -> Segment | None:
        """The segment on ``track`` live at frame ``i``, else the last one that ended."""
        t = float(self.t[i])
        before = [s for s in self.segs if s.track == track and s.start <= t + EPS]
        return max(before, key=lambda s: s.start, default=None)

    def path(self, site: str) -> FloatArray:
        """(N, 3) a body site's position over the frames, computed once per site."""
        if site not in self.paths:
            self.paths[site] = site_positions(self.skel, self.pose, site)
        return self.paths[site]

    def heights(self, sites: Sequence[str]) -> FloatArray:
        """(N, P) the sites' heights, from the cached paths (contacts and grips made most)."""
        return np.stack([self.path(site)[:, 1] for site in sites], axis=1)

    def where(self, seg: Segment) -> str:
        return " > ".join(seg.provenance.path)

    def pulled_during(self, k: int, side: str) -> str:
        """The words " during `...`" naming what moves at frame ``k`` when a ``side`` hand leaves
        what it rests on or holds: a posture, else the other arm's last segment, else anything."""
        other = ARM_TRACK["l" if side == "r" else "r"]
        by = self.posture_at(k) or self.last_on(other, k) or self.active(k)
        return f" during `{self.where(by)}`" if by is not None else ""

    # -- contact -----------------------------------------------------------------------------

    def contacts(self) -> None:
        """Each goal's effector on its site where the goal ends; shortfalls measured here."""
        n = len(self.t)
        rest = np.full(n, np.nan)
        root_starts = sorted(s.start for s in self.ir.on_track("root"))
        for track in ("r_arm", "l_arm"):
            segs = sorted(self.ir.on_track(track), key=lambda s: s.start)
            for k, seg in enumerate(segs):
                if not _is_goal(segs, k):
                    continue
                site = np.asarray(seg.goal.position, dtype=float)
                i = self.frame_at(seg.end)
                # the goal's frames: from its TA (the same site, ending where the TO starts); a
                # wrench stroke starts on its fastener and claims the tip back on it where it
                # ends, so its only frame is its end
                first = seg.start
                if k and segs[k - 1].kind == "TA" and _same_goal(segs[k - 1], seg):
                    first = segs[k - 1].start
                if is_stroke(seg):
                    first = seg.end
                i0 = min(self.frame_at(first), i)
                path = self.path(seg.goal.effector)
                dist = np.linalg.norm(path[i0 : i + 1] - site, axis=-1)
                error = float(dist[-1])
                j = int(np.argmin(dist))
                shortfall, closest = float(dist[j]), float(self.t[i0 + j])
                reached = _reachable(seg.result)
                self.v.contacts.append(
                    {
                        "effector": seg.goal.effector,
                        "site": seg.goal.site or "",
                        "time": float(self.t[i]),
                        "error": error,
                        "reached": reached,
                        "shortfall": shortfall,
                        "closest_time": closest,
                        "file": seg.provenance.origin.file,
                        "line": seg.provenance.origin.line,
                        "column": seg.provenance.origin.column,
                    }
                )
                if reached:
                    # resting: until the next segment on the arm or the root moves the body
                    nxt = segs[k + 1].start if k + 1 < len(segs) else math.inf
                    root = next((s for s in root_starts if s >= seg.end - EPS), math.inf)
                    lying = (self.t >= seg.end - EPS) & (self.t <= min(nxt, root) + EPS)
                    lying[i] = True
                    err = np.linalg.norm(path[lying] - site, axis=-1)
                    rest[lying] = np.fmax(rest[lying], err)
                    if error <= TOLERANCE:  # on the site where the goal ends: then pulled off?
                        self._judge_rest(seg, lying & (self.t > self.t[i] + EPS), path, site)
                self._judge_contact(seg, reached, error, shortfall, closest, float(self.t[i]))
        self.v.contact_error = rest
        self.report_shortfalls()

    def _judge_rest(
        self, seg: Segment, lying: np.ndarray, path: FloatArray, site: FloatArray
    ) -> None:
        """MT0511 for a hand that reached its site and is pulled off it while it rests there
        with its grip open, until its next grip event (a closed grip is ``grips``'s): the other
        hand's reach bending the trunk, a ``still``. The hold pass keeps it on; where the arm
        cannot follow, this is the finding (MT0520, the hold pass's own report, is retired)."""
        side = seg.goal.effector[:1]
        if side not in HAND_TRACK or seg.goal.effector != f"{side}_hand":
            return
        # until the hand's next grip event: a grasp makes it a grip (``grips``), a release
        # frees it (it then holds nothing)
        grip_starts = [
            g.start
            for g in self.ir.on_track(HAND_TRACK[side])
            if g.kind == "grip" and g.start >= seg.end - EPS
        ]
        until = min(grip_starts, default=math.inf)
        frames = lying & ~self._closed(side) & (self.t <= until + EPS)
        if not frames.any():
            return
        err = np.linalg.norm(path[frames] - site, axis=-1)
        j = int(np.argmax(err))
        if err[j] <= TOLERANCE:
            return
        k = int(np.flatnonzero(frames)[int(np.argmax(err > TOLERANCE))])  # first frame off
        during = self.pulled_during(k, side)
        self.report(
            "MT0511",
            f"the {HAND_NAMES[side]} resting on site `{seg.goal.site}` is {_mm(float(err[j]))} "
            f"mm off it at {self.t[np.flatnonzero(frames)[j]]:.2f} s{during}, though nothing "
            "it does moves it",
            seg.provenance.origin,
            ("rest", side, seg.goal.site),
        )

    def _closed(self, side: str) -> np.ndarray:
        """(N,) frames where the hand's grip is closed (from a grasp until the next release)."""
        closed = np.zeros(len(self.t), dtype=bool)
        state = False
        start = 0.0
        grips = sorted(
            (s for s in self.ir.on_track(HAND_TRACK[side]) if s.kind == "grip"),
            key=lambda s: s.start,
        )
        for g in grips:
            now = g.goal.params.get("state") == "closed"
            if now and not state:
                start = g.start
            elif state and not now:
                closed |= (self.t >= start - EPS) & (self.t < g.start - EPS)
            state = now
        if state:
            closed |= self.t >= start - EPS
        return closed

    def _judge_contact(self, seg: Segment, reached: bool, error: float, shortfall: float,
                       closest: float, at: float) -> None:  # fmt: skip
        """MT0510 for a claimed contact the frames miss; a shortfall is held per goal (line,
        site, arm) so that the closest approach over all its phases is the one reported."""
        who, site, ref = effector_name(seg.goal.effector), seg.goal.site, seg.provenance.origin
        if reached and error > TOLERANCE:
            self.report(
                "MT0510",
                f"the {who} is {_mm(error)} mm from site `{site}` at {at:.2f} s, where "
                f"`{self.where(seg)}` ends, though its solver reported the site reached",
                ref,
                (site, seg.track),
            )
        elif not reached and is_stroke(seg):
            key = (ref, site, seg.goal.effector)
            worst = self.stroke_short.get(key)
            if worst is None or error > worst[0]:
                self.stroke_short[key] = (error, at)
        elif not reached:
            key = (ref, site, seg.goal.effector)
            best = self.short.get(key)
            if best is None or shortfall < best[0]:
                self.short[key] = (shortfall, closest)

    def report_shortfalls(self) -> None:
        """MT0501 once per goal, with its closest approach on the frames (over 1 mm); a
        wrench's strokes with the worst distance where one of them ends."""
        for (ref, site, effector), (shortfall, closest) in self.short.items():
            if shortfall > TOLERANCE:
                self.report(
                    "MT0501",
                    f"the {effector_name(effector)} cannot reach site `{site}`: "
                    f"{_mm(shortfall)} mm short, closest at {closest:.2f} s",
                    ref,
                    (site, effector),
                    help=self.shortfall_help(effector, site, closest),
                )
        for (ref, site, effector), (error, at) in self.stroke_short.items():
            if error > TOLERANCE:
                self.report(
                    "MT0501",
                    f"the {effector_name(effector)} cannot stay on site `{site}` through its "
                    f"strokes: {_mm(error)} mm off at {at:.2f} s",
                    ref,
                    (site, effector),
                )

    def shortfall_help(self, effector: str, site: str | None, at: float) -> str | None:
        """What would bring a hand that falls short to its site, judged where it came closest:
        a reach moves the arm and the spine, never the feet or the pelvis, so a site below the
        knees of a standing body, one beyond the arm's length sideways or ahead, or one above
        the fingertips' reach needs a posture, a walk or a platform the task does not have."""
        side = effector[:2]
        where = next((s for s in self.ir.sites if s["name"] == site), None)
        if side not in ("r_", "l_") or where is None:
            return None
        target = np.asarray(where["position"], dtype=float)
        i = self.frame_at(at)
        joints = self.pose.p[i]
        j = self.skel.joint_index
        shoulder, elbow, wrist = (joints[j(side + n)] for n in ("shoulder", "elbow", "wrist"))
        hand = self.path(side + "hand")[i]
        arm = float(
            np.linalg.norm(elbow - shoulder)
            + np.linalg.norm(wrist - elbow)
            + np.linalg.norm(hand - wrist)
        )
        knee = min(float(joints[j("r_knee"), 1]), float(joints[j("l_knee"), 1]))
        pelvis = float(joints[j("pelvis"), 1]) - self.ir.ground
        standing = pelvis > STANDING_PELVIS * float(self.skel.root_position[1])
        ahead = target - shoulder
        up, across = float(ahead[1]), float(np.hypot(ahead[0], ahead[2]))
        if standing and target[1] < knee:
            return (
                "a reach moves the arm and the spine, not the feet or the pelvis (bend flexes "
                "the spine only): squat() or kneel() before it to bring the shoulders down"
            )
        if float(np.linalg.norm(ahead)) <= arm:
            return None  # within the arm's length: its joints' limits, not the distance
        if up > across:
            return (
                "the site is above this manikin's reach from where it stands: lower the work, "
                "or check a taller percentile (a step or platform is not modelled)"
            )
        return (
            "a reach keeps the feet where they are: walk_to a site nearer to it first, or "
            "bring the work closer"
        )

    def pass_claims(self) -> None:
        """The passes' claims verify did not measure (a screw the wrist cannot turn) go out in
        the passes' words; reach shortfalls and balance are reported as measured."""
        for code, message, ref, kw in self.claims:
            if code == "MT0502" or (code == "MT0501" and "cannot reach site" in message):
                continue
            self.ctx.emit(code, message, ref, **kw)
            self.v.findings.append(
                {"code": code, "message": message, "line": ref.line, "column": ref.column}
            )

    # -- grips -------------------------------------------------------------------------------

    def grips(self) -> None:
        """A closed hand holds still while nothing moves it: no segment on its arm or hand
        track (a reach or move, a turn), no walk (the part is carried from then on) and no
        posture through which the hand carries its part (``hold.carried_postures``: the grip
        takes the part somewhere before it opens); grip segments themselves move nothing, and
        neither does any other whole-body posture: a squat or a kneel with a hand closed on a
        part that stays keeps the hand on it (the hold pass), or it has let go (this finding;
        the hold pass's own MT0520 is retired)."""
        t = self.t
        moving_root = [s for s in self.ir.on_track("root") if s.kind == "locomotion"]
        carried = carried_postures(self.ir)
        for side in ("r", "l"):
            grips = sorted(
                (s for s in self.ir.on_track(HAND_TRACK[side]) if s.kind == "grip"),
                key=lambda s: s.start,
            )
            closed = np.zeros(len(t), dtype=bool)
            part = np.full(len(t), "", dtype=object)  # the two-handed goal's site it holds
            held_by: list[tuple[float, float, Segment]] = []
            for k, g in enumerate(grips):
                if g.goal.params.get("state") != "closed":
                    continue
                opens = [o.start for o in grips[k + 1 :] if o.goal.params.get("state") == "open"]
                end = min(opens, default=math.inf)
                window = (t >= g.start - EPS) & (t < end - EPS)
                closed |= window
                held_by.append((g.start, end, g))
                # the goal the hand closes on: the last contact of its arm before the grip
                reach = max(
                    (r for r in self.ir.on_track(ARM_TRACK[side])
                     if r.kind == "TO" and r.end <= g.start + EPS),
                    key=lambda r: r.end,
                    default=None,
                )  # fmt: skip
                if (
                    reach is not None
                    and reach.goal.params.get("two_handed")
                    and reach.goal.site
                    and _reachable(reach.result)  # a hand short of the part holds nothing
                ):
                    part[window] = reach.goal.site
            self.held[side] = (part, held_by)
            if not closed.any():
                continue
            movers = (
                [
                    s
                    for s in (
                        *self.ir.on_track(ARM_TRACK[side]),
                        *self.ir.on_track(HAND_TRACK[side]),
                    )
                    if s.kind != "grip"
                ]
                + moving_root
                + carried[ARM_TRACK[side]]
            )
            still = closed.copy()
            for s in movers:
                still &= ~((t > s.start + EPS) & (t < s.end - EPS))
            hand = self.path(f"{side}_hand")
            for first, last in failure_runs(still, gap=1):
                seg_grip = next(
                    (g for a, b, g in reversed(held_by) if a - EPS <= t[first] < b), None
                )
                if seg_grip is None:
                    continue
                drift = np.linalg.norm(hand[first : last + 1] - hand[first], axis=-1)
                j = int(np.argmax(drift))
                worst = float(drift[j])
                self.v.grips.append(
                    {
                        "hand": f"{side}_hand",
                        "t_start": float(t[first]),
                        "t_end": float(t[last]),
                        "drift": worst,
                        "time": float(t[first + j]),
                        "line": seg_grip.provenance.origin.line,
                    }
                )
                if worst > TOLERANCE:
                    # what moves when the hand first leaves is what pulls it off
                    k = first + int(np.argmax(drift > TOLERANCE))
                    during = self.pulled_during(k, side)
                    self.report(
                        "MT0511",
                        f"the {HAND_NAMES[side]} holding a part moves {_mm(worst)} mm from "
                        f"{t[first]:.2f} s to {t[first + j]:.2f} s{during}, though nothing "
                        "it does moves the part",
                        seg_grip.provenance.origin,
                        ("grip", side),
                    )

    def both_hands(self) -> None:
        """A part both hands hold (a two-handed goal, both grips closed on it) is rigid: the
        distance between the two grip points stays what it was when the second hand closed,
        whatever moves them (the part is carried by both)."""
        if set(self.held) != {"r", "l"}:
            return
        (right, r_by), (left, _) = self.held["r"], self.held["l"]
        same = (right != "") & (right == left)
        if not same.any():
            return
        gap = np.linalg.norm(self.path("r_hand") - self.path("l_hand"), axis=-1)
        t = self.t
        for first, last in failure_runs(same, gap=1):
            stretch = np.abs(gap[first : last + 1] - gap[first])
            j = int(np.argmax(stretch))
            worst = float(stretch[j])
            grasp = next((g for a, b, g in reversed(r_by) if a - EPS <= t[first] < b), None)
            if grasp is None:
                continue
            self.v.grips.append(
                {
                    "hand": "both",
                    "t_start": float(t[first]),
                    "t_end": float(t[last]),
                    "drift": worst,
                    "time": float(t[first + j]),
                    "line": grasp.provenance.origin.line,
                }
            )
            if worst > TOLERANCE:
                by = self.active(first + j, ("r_arm", "l_arm"))
                during = f" during `{self.where(by)}`" if by is not None else ""
                self.report(
                    "MT0511",
                    f"the two hands holding the part at `{right[first]}` move "
                    f"{_mm(worst)} mm {'apart' if gap[first + j] > gap[first] else 'together'} "
                    f"(from {gap[first] * 1000:.0f} mm at {t[first]:.2f} s to "
                    f"{gap[first + j] * 1000:.0f} mm at {t[first + j]:.2f} s){during}, though the "
                    "part is rigid",
                    grasp.provenance.origin,
                    ("both", right[first]),
                )

    # -- the floor ---------------------------------------------------------------------------

    def floor(self) -> None:
        """Depth below the floor of each class of body point, per frame."""
        skel, ground = self.skel, self.ir.ground
        tools = [s.name for s in skel.sites if "_tool_" in s.name]
        classes: dict[str, tuple[FloatArray, list[str]]] = {
            "joints": (self.pose.p[..., 1], list(skel.joint_names)),
            "soles": (self.heights(SOLE_SITES), list(SOLE_SITES)),
            "hands": (self.heights(("r_hand", "l_hand")), ["r_hand", "l_hand"]),
            "fingertips": (
                self.heights(("r_fingertip", "l_fingertip")),
                ["r_fingertip", "l_fingertip"],
            ),
        }
        if tools:
            classes["tool tips"] = (self.heights(tools), tools)
        every = np.zeros(len(self.t))
        for name, (heights, names) in classes.items():
            depth_pts = np.maximum(ground - heights, 0.0)  # (N, P)
            depth = depth_pts.max(axis=1)
            every = np.maximum(every, depth)
            k = deepest(depth)
            self.v.penetration[name] = {"depth": float(depth[k]), "time": float(self.t[k])}
            for first, last in failure_runs(depth > TOLERANCE):
                i = first + deepest(depth[first : last + 1])
                point = names[int(np.argmax(depth_pts[i]))]
                side = point[0] if point[:2] in ("r_", "l_") else ""
                seg = self.active(i, [ARM_TRACK[side]] if side and name != "soles" else [])
                if seg is None:
                    continue
                self.report(
                    "MT0512",
                    f"{point_name(point)} goes {_mm(float(depth[i]))} mm below the floor at "
                    f"{self.t[i]:.2f} s in `{self.where(seg)}`",
                    seg.provenance.origin,
                    ("floor", name),
                )
        self.v.penetration_frames = every

    # -- joint limits ------------------------------------------------------------------------

    def limits(self) -> None:
        skel, q = self.skel, self.ir.frames.q  # type: ignore[union-attr]
        above, below = q - skel.upper, skel.lower - q
        over = np.maximum(np.maximum(above, below), 0.0)
        self.v.limit_excess = np.where(above > 0.0, above, np.where(below > 0.0, -below, 0.0))
        bad = over > LIMIT_TOLERANCE
        self.v.limits = {"count": int(np.count_nonzero(bad)), "excess": 0.0, "dof": "",
                         "time": math.nan}  # fmt: skip
        if not bad.any():
            return
        d = int(np.argmax(over.max(axis=0)))
        i = int(np.argmax(over[:, d]))
        self.v.limits.update(excess=float(over[i, d]), dof=skel.dof_names[d],
                             time=float(self.t[i]))  # fmt: skip
        for d in np.flatnonzero(bad.any(axis=0)):
            name = skel.dof_names[d]
            for first, last in failure_runs(bad[:, d]):
                i = first + int(np.argmax(over[first : last + 1, d]))
                side = name[0] if name[:2] in ("r_", "l_") else ""
                seg = self.active(i, [ARM_TRACK[side]] if side else [])
                if seg is None:
                    continue
                which = "upper" if above[i, d] >= below[i, d] else "lower"
                self.report(
                    "MT0513",
                    f"joint `{name}` is {math.degrees(float(over[i, d])):.2f}° past its "
                    f"{which} limit at {self.t[i]:.2f} s in `{self.where(seg)}`",
                    seg.provenance.origin,
                    ("limit", name),
                )

    # -- balance -----------------------------------------------------------------------------

    def balance(self) -> None:
        """Static margin of the centre of mass (with held tools) over the touching points."""
        ir, t = self.ir, self.t
        margin = np.empty(len(t))
        # a chunk of frames at a time, as the balance pass: the hull's candidate edges cost
        # ~5 KB a frame while measured (600 MB at once for an hour of motion). The support is
        # the points that touch, whatever the steps' records say (``touching_support``)
        for a in range(0, len(t), CHUNK_FRAMES):
            c = slice(a, a + CHUNK_FRAMES)
            margin[c] = balance_margin(ir, self.pose.rows(c), t[c])
        static = ~walking(ir, t)
        self.v.support_margin, self.v.static = margin, static
        sel = np.flatnonzero(static & ~np.isnan(margin))
        if sel.size:
            k = sel[int(np.argmin(margin[sel]))]
            self.v.static_margin, self.v.static_margin_time = float(margin[k]), float(t[k])
        # a static frame where no point touches (NaN) has no support at all: it fails too
        failed = static & ~(margin >= MIN_MARGIN)
        for first, last in failure_runs(failed):
            part = np.where(failed[first : last + 1], margin[first : last + 1], np.inf)
            seg = self.active(first)
            if seg is None:
                continue
            when = f"at {t[first]:.2f} s" if last == first else (
                f"from {t[first]:.2f} s to {t[last]:.2f} s")  # fmt: skip
            if np.isnan(part).all():
                what = "no point of the body touches the floor or a site"
            else:
                worst = -float(np.nanmin(part))
                what = f"the centre of mass is up to {_mm(worst)} mm outside the support of the "
                what += "points that touch"
            self.report(
                "MT0502",
                f"the manikin loses its balance in `{self.where(seg)}`: {when} {what}",
                seg.provenance.origin,
                ("balance", id(seg)),
            )

    # -- the body's own volume ---------------------------------------------------------------

    def body(self) -> None:
        """Hands and forearms outside the trunk and the thighs (``mtlc.body.capsules``)."""
        f = self.ir.frames
        assert f is not None
        runs = repeated_rows(f.q, f.root_position, f.root_rotation)
        if runs is None:
            depth, pairs = self_intersection(self.skel, self.pose)
        else:  # a run of identical frames (a hold) is as deep as its first (the same numbers)
            heads, at = runs
            depth, pairs = self_intersection(self.skel, self.pose.rows(heads))
            depth = depth[at]
        per_frame = depth.max(axis=1)
        self.v.intersection_frames = per_frame
        k = int(np.argmax(per_frame))
        c = int(np.argmax(depth[k]))
        self.v.self_intersection = {
            "depth": max(float(per_frame[k]), 0.0),
            "time": float(self.t[k]),
            "limb": pairs[c][0] if per_frame[k] > 0 else "",
            "part": pairs[c][1] if per_frame[k] > 0 else "",
        }
        worst: dict[SourceRef, tuple[float, int, int, Segment]] = {}  # the deepest per line

        def deepest(i: int, c: int, seg: Segment | None) -> None:
            if seg is None:
                return
            ref = seg.provenance.origin
            if ref not in worst or depth[i, c] > worst[ref][0]:
                worst[ref] = (float(depth[i, c]), i, c, seg)

        for c, (limb, _) in enumerate(pairs):
            for first, last in failure_runs(depth[:, c] > TOLERANCE):
                i = first + int(np.argmax(depth[first : last + 1, c]))
                deepest(i, c, self.active(i, [ARM_TRACK["r" if limb.startswith("right") else "l"]]))
                # and at every other line live while it is as deep, within ``NEAR_DEEPEST``:
                # which frame of a long, even run is the deepest is a matter of a tenth of a
                # millimetre, and whoever reads the output finds the finding at the line live
                # at the frame they measured
                for seg in self.segs:
                    if seg.end < self.t[first] - EPS or seg.start > self.t[last] + EPS:
                        continue
                    a = max(first, int(np.searchsorted(self.t, seg.start - EPS)))
                    b = min(last + 1, int(np.searchsorted(self.t, seg.end + EPS, "right")))
                    inside = np.flatnonzero(depth[a:b, c] > depth[i, c] - NEAR_DEEPEST)
                    if inside.size:
                        k = a + int(inside[np.argmax(depth[a + inside, c])])
                        deepest(k, c, seg)
        for ref, (d, i, c, seg) in worst.items():
            limb, part = pairs[c]
            self.report(
                "MT0514",
                f"the {limb} goes {_mm(d)} mm into the {part} at {self.t[i]:.2f} s in "
                f"`{self.where(seg)}`",
                ref,
                ("body",),
            )

    # -- the equipment -----------------------------------------------------------------------

    def equipment(self) -> None:
        """The body's capsules and the held tools outside the scene's models (MT0515): one
        finding per task line, part, model and goal, at its deepest frame. A hand or its tool at its
        goal's site (``at_site``) touches the model the site is on: not a finding."""
        models = {m.name: m for m in self.ir.geometry if len(m.faces)}
        if not models:
            return
        held = held_parts(self.ir, list(models.values()), self.pose)
        indices, faces_of, pieces = scene_pieces(list(models.values()), held)
        fc = frame_clearance(self.ir, indices, pose=self.pose, through=True, held=pieces)
        self.v.equipment_clearance = fc
        columns = {**indices, **{part.column: index for part, index in pieces}}
        depth = np.where(np.isnan(fc.clearance), -np.inf, -fc.clearance)
        caps = collision_capsules(self.skel) + tuple(cap for cap, _, _ in held_capsules(self.ir))
        radii = np.array([cap.radius for cap in caps])
        sides = self.capsule_sides(fc)
        goal_at = self.at_site(fc, columns, sides, radii, depth)
        self.in_hand(fc, held, depth)
        fc.excused = np.isneginf(depth) & ~np.isnan(fc.clearance)
        self.v.held_parts = held
        _, c, m = depth.shape
        k = int(np.argmax(depth.reshape(-1)))
        i, rest = divmod(k, c * m)
        self.v.equipment = {
            "depth": max(float(depth.reshape(-1)[k]), 0.0),
            "part": fc.capsules[rest // m] if depth.reshape(-1)[k] > 0 else "",
            "model": fc.meshes[rest % m].split("/")[0] if depth.reshape(-1)[k] > 0 else "",
            "time": float(self.t[i]),
        } | ({"held": [self.held_record(part) for part in held]} if held else {})
        # per (line, part, model, goal site) its deepest frame, the column (a held part is a
        # column of its own, ``model/node``) and the goal at the site then: a `for` over four
        # bolts is one line and four goals, each reported (one finding per line left three of
        # them a hand through the panel without a word)
        worst: dict[
            tuple[SourceRef, str, str, str | None], tuple[float, int, Segment, Segment | None, str]
        ]
        worst = {}
        for j, part in enumerate(fc.capsules):
            side = sides[j]
            tracks = [ARM_TRACK[side], HAND_TRACK[side]] if side else ["root"]
            episode = self.episodes(tracks)
            for col, column in enumerate(fc.meshes):
                for first, last in failure_runs(depth[:, j, col] > EQUIPMENT_TOLERANCE):
                    # one episode per segment of the part's tracks: a hand through the panel
                    # at its pick and then on the walk away is two findings, at two lines
                    labels = episode[first : last + 1]
                    cuts = first + np.flatnonzero(np.diff(labels)) + 1
                    for a, b in zip(np.r_[first, cuts], np.r_[cuts - 1, last], strict=True):
                        i = a + deepest(depth[a : b + 1, j, col])
                        seg = self.active(i, tracks)
                        # runs closer than a few frames merge: a piece cut off by a segment's
                        # start may hold only the frames between two runs (-inf: excused)
                        if seg is None or not depth[i, j, col] > EQUIPMENT_TOLERANCE:
                            continue
                        goal = goal_at[i].get(side) if side and seg.track in tracks else None
                        site = goal.goal.site if goal is not None else None
                        key = (seg.provenance.origin, part, column.split("/")[0], site)
                        if key not in worst or _noise_free(depth[i, j, col]) > _noise_free(
                            worst[key][0]
                        ):
                            worst[key] = (float(depth[i, j, col]), i, seg, goal, column)
        by_column = {part.column: part for part in held}
        for (_, part, model, _site), (d, i, seg, goal, column) in worst.items():
            j = fc.capsules.index(part)
            a, b, radius = capsule_segments(self.skel, self.pose.rows(slice(i, i + 1)),
                                            (caps[j],))  # fmt: skip
            node = None
            if column in by_column:  # a held part: the query in its own frame, its node named
                node = by_column[column].node or model
            else:
                face = columns[column].touched_face(a[0, 0], b[0, 0], radius[0])
                if face is not None and column in faces_of:
                    face = int(faces_of[column][face])
                node = models[model].part_of(face)
            self.report_collision(part, model, node, d, float(self.t[i]), seg, goal)
        self.carried(fc, held, faces_of)

    def carried(self, fc: FrameClearance, held: list[HeldPart], faces_of: dict[str, Any]) -> None:
        """MT0515 for a held part in the rest of the equipment (``FrameClearance.held_depth``):
        the hand holding it is excused against it (``in_hand``), the part is not excused
        against the walls it is carried through. One finding per task line, part and model,
        at its deepest frame and the line of the segment that moves the hand carrying it."""
        models = {m.name: m for m in self.ir.geometry if len(m.faces)}
        worst: dict[tuple[SourceRef, str, str], tuple[float, int, Segment, str | None]] = {}
        for h, part in enumerate(held):
            for col, column in enumerate(fc.meshes):
                depth = np.nan_to_num(fc.held_depth[:, h, col], nan=-np.inf)
                for i in np.flatnonzero(depth > EQUIPMENT_TOLERANCE):
                    side = next(
                        x.side for x in part.holds if x.start - EPS <= self.t[i] <= x.end + EPS
                    )
                    seg = self.active(i, [ARM_TRACK[side], HAND_TRACK[side]])
                    if seg is None:
                        continue
                    label = f"held part `{part.node or part.model}`"
                    key = (seg.provenance.origin, label, column)
                    if key not in worst or depth[i] > worst[key][0]:
                        face = int(fc.held_face[i, h, col])
                        if face >= 0 and column in faces_of:
                            face = int(faces_of[column][face])
                        node = models[column].part_of(face if face >= 0 else None)
                        worst[key] = (float(depth[i]), int(i), seg, node)
        for (_, label, model), (d, i, seg, node) in sorted(worst.items(), key=lambda kv: kv[1][1]):
            self.report_collision(label, model, node, d, float(self.t[i]), seg, None)

    def in_hand(self, fc: FrameClearance, held: list[HeldPart], depth: FloatArray) -> None:
        """A hand on a part it grasps is not in it (docs/collision.md, "Held parts"): the hand
        capsule is a closed fist, and a grip wraps the part it holds. Each grasping hand
        against its part is excused (``depth`` set to -inf) from the frame its goal brings it
        within ``CONTACT_ZONE`` of the node (the grasp's start at the latest) until that hand's
        next goal after the release starts; its forearm, the other limbs and the other hand
        (unless it holds the part too) are measured against the part where it is."""
        for part in held:
            col = fc.meshes.index(part.column)
            for hold in part.holds:
                j = fc.capsules.index(HAND_NAMES[hold.side])
                goal = hold.goal
                site = np.asarray(goal.goal.position, dtype=float).reshape(-1, 3)[0]
                near = np.linalg.norm(self.path(goal.goal.effector) - site, axis=-1) <= CONTACT_ZONE
                # from the reach that brought it there (the TA before a TO of the same line)
                came = min(
                    (s.start for s in self.ir.on_track(goal.track)
                     if s.goal.site == goal.goal.site and s.provenance.origin ==
                     goal.provenance.origin and s.end <= hold.start + EPS),
                    default=goal.start,
                )  # fmt: skip
                arrive = np.flatnonzero(
                    near & (self.t >= came - EPS) & (self.t <= hold.start + EPS)
                )
                start = self.t[arrive[0]] if arrive.size else hold.start
                later = [
                    s.start for s in self.ir.on_track(ARM_TRACK[hold.side])
                    if s.kind in ("TA", "TO") and s.start >= hold.end - EPS
                ]  # fmt: skip
                until = min(later, default=math.inf)
                window = (self.t >= start - EPS) & (self.t < until - EPS)
                depth[window, j, col] = -np.inf

    def held_record(self, part: HeldPart) -> dict[str, Any]:
        """What the IR JSON says of a held part: its model, node and grasped node, and each
        hand's hold (side, start, end; s)."""
        return {
            "model": part.model,
            "node": part.node or "",
            "at": part.marker,
            "holds": [[h.side, round(h.start, 6), round(h.end, 6)] for h in part.holds],
        }

    def episodes(self, tracks: list[str]) -> np.ndarray:
        """(N,) a label per frame that changes where a segment on ``tracks`` starts or ends."""
        bounds = sorted({x for s in self.segs if s.track in tracks for x in (s.start, s.end)})
        return np.searchsorted(np.asarray(bounds, dtype=float), self.t + EPS)

    def capsule_sides(self, fc: FrameClearance) -> list[str]:
        """Each arm capsule's side ("r", "l"), a held tool its hand's (the held capsules come
        after the body's, in ``held_capsules``'s order); "" for the head, trunk and legs,
        which the root's segments move."""
        held = [cap.start[0][:1] for cap, _, _ in held_capsules(self.ir)]
        body = len(fc.capsules) - len(held)
        words = {"right": "r", "left": "l"}
        arm = ("upper arm", "forearm", "hand")
        return [
            words.get(name.split(" ")[0], "") if name.endswith(arm) else ""
            for name in fc.capsules[:body]
        ] + held

    def at_site(
        self,
        fc: FrameClearance,
        indices: dict[str, Any],
        sides: list[str],
        radii: FloatArray,
        depth: FloatArray,
    ) -> list[dict[str, Segment]]:
        """Where a goal's effector is within ``CONTACT_ZONE`` of its site (from the goal's
        start until its track's next goal at another site), its hand and that hand's tools
        touching a model within ``CONTACT_ZONE`` of the site are excused (``depth`` set to
        -inf there): in by at most their radius and ``EQUIPMENT_TOLERANCE``, their surface
        on the model's, not through it (a hand whose fingers go through the panel it unbolts
        is reported). Returns, per frame, the goal each side is at (the "not reachable
        without collision" wording for what else goes in there)."""
        n = len(self.t)
        goal_at: list[dict[str, Segment]] = [{} for _ in range(n)]
        near: dict[tuple[float, ...], list[int]] = {}
        for track in ("r_arm", "l_arm", "r_hand", "l_hand"):
            segs = sorted(self.ir.on_track(track), key=lambda s: s.start)
            goals = [s for s in segs if s.kind in ("TA", "TO") and s.goal.position is not None]
            side = track[:1]
            parts = [j for j, name in enumerate(fc.capsules) if sides[j] == side and (
                name.endswith(" hand") or name.startswith("tool "))]  # fmt: skip
            for k, seg in enumerate(goals):
                site = np.asarray(seg.goal.position, dtype=float).reshape(-1, 3)[0]
                later = [g.start for g in goals[k + 1 :] if g.goal.site != seg.goal.site]
                until = min(later, default=math.inf)
                window = (self.t >= seg.start - EPS) & (self.t < until - EPS)
                dist = np.linalg.norm(self.path(seg.goal.effector) - site, axis=-1)
                there = np.flatnonzero(window & (dist <= CONTACT_ZONE))
                if not there.size:
                    continue
                key = tuple(site.round(6))
                if key not in near:
                    near[key] = [
                        col for col, name in enumerate(fc.meshes)
                        if indices[name].segment_distance(site, site)[0] <= CONTACT_ZONE
                    ]  # fmt: skip
                for col in near[key]:
                    block = depth[np.ix_(there, parts, [col])]
                    touch = block <= radii[parts][None, :, None] + EQUIPMENT_TOLERANCE
                    depth[np.ix_(there, parts, [col])] = np.where(touch, -np.inf, block)
                for i in there:
                    goal_at[i].setdefault(side, seg)
        return goal_at

    def report_collision(self, part: str, model: str, node: str | None, depth: float,
                         time: float, seg: Segment, goal: Segment | None) -> None:  # fmt: skip
        """MT0515: ``part`` ``depth`` m into ``model`` (its ``node``) at ``time``, at ``seg``'s
        line; worded as a goal not reachable without collision when at ``goal``'s site."""
        where = f"model `{model}`" + (f" (node `{node}`)" if node and node != model else "")
        what = f"the {part.removeprefix('tool ')} goes {_mm(depth)} mm into {where} at {time:.2f} s"
        if goal is not None:
            message = (
                f"site `{goal.goal.site}` is not reachable without collision: {what}, with "
                f"the {effector_name(goal.goal.effector)} at the site"
            )
        else:
            message = f"{what} in `{self.where(seg)}`"
        site = goal.goal.site if goal is not None else None
        self.report("MT0515", message, seg.provenance.origin, ("equipment", part, model, site))


def verify(ir: MotionIR, ctx: PassContext) -> Verification:
    """Measure every claim on ``ir``'s frames, report each failure, return the figures."""
    start = clock.perf_counter()
    v = _Verifier(ir, ctx)
    v.contacts()
    v.pass_claims()
    v.grips()
    v.both_hands()
    v.floor()
    v.limits()
    v.balance()
    v.body()
    v.equipment()
    v.v.seconds = clock.perf_counter() - start
    return v.v


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.frames is None or ir.skeleton is None or len(ir.frames.time) == 0:
        ctx.flush_claims()
        return ir
    ir.verification = verify(ir, ctx)
    return ir


def _is_goal(segs: list[Segment], k: int) -> bool:
    """A segment whose end the task claims the effector at its site: every TO, and a TA that no
    TO on the same site follows (a goal with ``approach 0``, a move's last leg such as
    ``slide_out``): those were left unchecked, and missed by 150-210 mm without a word."""
    seg = segs[k]
    if seg.goal.position is None or seg.kind not in ("TO", "TA"):
        return False
    if seg.kind == "TO":
        return True
    nxt = segs[k + 1] if k + 1 < len(segs) else None
    return not (nxt is not None and nxt.kind == "TO" and _same_goal(seg, nxt))


def _same_goal(ta: Segment, to: Segment) -> bool:
    """A TA and the TO after it are one goal when one task line asked for both on one site: a
    reach with ``approach 0`` then another reach to the same site (a TO alone: its hand is at
    the approach point already) are two goals, and the first was left unchecked (2 m short,
    no diagnostic)."""
    return ta.goal.site == to.goal.site and ta.provenance.origin == to.provenance.origin
