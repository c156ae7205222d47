"""Every claim of a compile, checked on its output files with our own kinematics (issue 18).

    python bench/motion.py [--generated 200] [--manikins female-p5,male-p95] [--examples all]
                           [--walks] [--procedures] [--workers 2] [--save DIR] [--worst 10]
                           [--steps 3:8] [--seed0 0]

Compiles the examples with each of the 14 GB 10000-88 manikins and ``--generated`` procedures
from tests/strategies/procedures.py (seeds ``seed0..``) with each of ``--manikins`` (``--examples
none`` / ``--generated 0`` leave a half out; ``--walks`` adds bench/walks, ``--procedures``
bench/procedures: hand-written maintenance procedures no example or test covers), each job in a worker process through the command
line's own entry point (`mtlc compile FILE --manikin M --target ir --format json`). Then it reads
the IR JSON back and measures the frames a user receives with forward kinematics written here
from docs/ir.md's rule (numpy only: no mtlc pass, metric or kinematics is used to measure), and
the diagnostics the compile printed. Definitions (docs/testing.md, "bench/motion.py"):

* silent miss: a goal (the last phase of a reach or move, every wrench stroke) whose effector
  (hand, or tool tip) is more than 1 mm from its position at the first output frame at or after
  the goal's end, with no motion diagnostic (MT05xx, MT0900) at the goal's task line;
* contact error: that distance, the largest over the goals of a compile;
* penetration: how far the lowest body point (every joint, effector, contact point and landmark,
  fingertips included, and a held tool's tip) is below the floor, over all frames;
* floating: how far the lowest body point is above the floor at the worst frame (walking has no
  flight phase, so something always touches);
* grip drift: how far a closed hand moves on a part that stays put, i.e. from its grasp until that
  hand's first reach or move, while neither that hand's own segments nor a walk move it;
* true static margin: the horizontal distance from the centre of mass (body, held tools, carried
  loads) to the edge of the convex hull of the points that touch (within 2 mm of the floor, or a
  hand within 2 mm of one of its goal positions), negative outside; frames outside walks only;
* hands inside the body: docs/metrics.md's one definition, measured here on its own: how deep
  the surface of a hand or forearm capsule goes into the trunk or a thigh capsule, radii from
  the manikin's GB 10000-88 row (read from the table's data file); over 1 mm it is inside, and
  silent when no MT0514 names a task line live at the deepest frame;
* joint step: the largest change of one degree of freedom between two output frames.

No timing is asserted: this prints a table (the issue's goals beside each figure) and the worst
cases with a command that reproduces each (``--save DIR`` keeps the generated procedures).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import json
import math
import multiprocessing
import shutil
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "bench"))

import human  # noqa: E402  (issue 19's figures)
from strategies.procedures import generate  # noqa: E402

EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
WALKS = sorted((ROOT / "bench" / "walks").glob("*.mtask"))  # --walks: the gait's own procedures
# --procedures: hand-written maintenance procedures that no example, test or tuning has seen
PROCEDURES = sorted((ROOT / "bench" / "procedures").glob("*.mtask"))
MANIKINS = tuple(
    f"{sex}-p{pct}" for sex in ("female", "male") for pct in (1, 5, 10, 50, 90, 95, 99)
)
KNEE_DEPTH = 0.05  # m: half a knee's depth; a kneeling knee bears this far below its centre
LOAD_RAMP = 0.3  # s: a carried load is taken up and put down over this (docs/metrics.md)
KNEE_HALF_WIDTH = 0.025  # m: half a patella's breadth; the knee bears over this either side
MISS_TOL = 1e-3  # m: a goal further than this from its effector is a miss
TOUCH_TOL = 2e-3  # m: a point supports only this close to the floor or to its site
LOOSE_TOL = 1e-2  # m: mtlc's own contact tolerance (docs/metrics.md), for comparison
INSIDE_TOL = 1e-3  # m: a limb this deep in the body touches it; deeper is inside (docs/metrics.md)
FOREARM_OF_HAND_BREADTH = 0.36  # the forearm's radius, of the hand breadth (docs/metrics.md)
HAND_OF_HAND_BREADTH = 0.25  # the hand's radius
GB10000_CSV = ROOT / "src" / "mtlc" / "body" / "data" / "gb10000_1988.csv"
UNRELATED = ("MT06",)  # lint's findings do not name a motion claim
Array = np.ndarray


# ------------------------------------------------------------------ forward kinematics
def axis_angle(axis: Any, angle: Array) -> Array:
    """(T, 3, 3) rotations about one unit axis by T angles (Rodrigues)."""
    x, y, z = (float(c) for c in axis)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def quat_matrix(q: Array) -> Array:
    """(T, 3, 3) rotations of (T, 4) unit quaternions, w first."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def joint_transforms(doc: dict[str, Any]) -> dict[str, tuple[Array, Array]]:
    """World rotation (T, 3, 3) and position (T, 3) of every joint at every output frame: the rule
    of docs/ir.md (parents first; parent transform, then the offset, then the dofs in order)."""
    f = doc["frames"]
    q = np.asarray(f["q"], float).reshape(len(f["time"]), -1)
    col = {name: k for k, name in enumerate(f["dof_names"])}
    world: dict[str, tuple[Array, Array]] = {}
    for joint in doc["manikin"]["joints"]:
        off = np.asarray(joint["offset"], float)
        if joint["parent"] is None:
            R = quat_matrix(np.asarray(f["root_rotation"], float))
            p = np.asarray(f["root_position"], float) + R @ off
        else:
            Rp, pp = world[joint["parent"]]
            R, p = Rp, pp + Rp @ off
        for dof in joint["dofs"]:
            R = R @ axis_angle(dof["axis"], q[:, col[dof["name"]]])
        world[joint["name"]] = (R, p)
    return world


def hand_to_joint(v: Any, side: str) -> Array:
    """A point of the hand's frame (x thumb, y fingers, z palm) in the wrist joint's frame, as
    docs/tools.md states it: x -> +Z, y -> -Y, z -> +X (right hand; the left is mirrored)."""
    x, y, z = (float(c) for c in v)
    return np.array([z if side == "r" else -z, -y, x])


@dataclass
class Body:
    """Every named point of one compile at every output frame, and what it needs to judge them."""

    doc: dict[str, Any]
    time: Array
    world: dict[str, tuple[Array, Array]]
    points: dict[str, Array] = field(default_factory=dict)  # name -> (T, 3)
    tools: dict[str, tuple[dict[str, Any], float, float]] = field(default_factory=dict)

    @classmethod
    def of(cls, doc: dict[str, Any]) -> Body:
        world = joint_transforms(doc)
        body = cls(doc, np.asarray(doc["frames"]["time"], float), world)
        m = doc["manikin"]
        for name, (_, p) in world.items():
            body.points[name] = p
        for spec in m["effectors"] + m["contact_points"] + m.get("landmarks", []):
            R, p = world[spec["joint"]]
            body.points[spec["name"]] = p + R @ np.asarray(spec["offset"], float)
        hands = {e["name"]: e for e in m["effectors"]}
        for seg in doc["segments"]:
            goal = seg.get("goal") or {}
            tool = (goal.get("params") or {}).get("tool")
            side = str(goal.get("effector", ""))[:1]
            if not isinstance(tool, dict) or side not in ("r", "l"):
                continue
            name = f"{side}_tool_{tool['name']}"
            if name not in body.tools:
                hand = hands[f"{side}_hand"]
                grip = np.asarray(tool.get("grip", (0.0, 0.0, 0.0)), float)
                tip = np.asarray(tool.get("tip", grip), float)
                off = np.asarray(hand["offset"], float) + hand_to_joint(tip - grip, side)
                R, p = world[hand["joint"]]
                body.points[name] = p + R @ off
                body.tools[name] = (tool, seg["t_start"], seg["t_end"])
            t, start, end = body.tools[name]
            body.tools[name] = (t, min(start, seg["t_start"]), max(end, seg["t_end"]))
        return body

    def frame_at(self, t: float) -> int:
        """The first output frame at or after ``t`` (the last frame when none is)."""
        k = int(np.searchsorted(self.time, t - 1e-9))
        return min(k, len(self.time) - 1)

    def active(self, segments: list[dict[str, Any]]) -> Array:
        """(T,) frames inside any of the segments (start < t < end)."""
        on = np.zeros(len(self.time), bool)
        for s in segments:
            on |= (self.time > s["t_start"] + 1e-9) & (self.time < s["t_end"] - 1e-9)
        return on

    def com(self) -> Array:
        """(T, 3) centre of mass of the segments, the held tools and the carried loads."""
        total = np.zeros((len(self.time), 3))
        mass = np.zeros(len(self.time))
        for joint in self.doc["manikin"]["joints"]:
            R, p = self.world[joint["name"]]
            total += joint["mass"] * (p + R @ np.asarray(joint["com"], float))
            mass += joint["mass"]
        for name, (tool, start, end) in self.tools.items():
            held = (self.time >= start) & (self.time <= end)
            middle = 0.5 * (self.points[name] + self.points[f"{name[0]}_hand"])
            total += float(tool.get("mass", 0.0)) * held[:, None] * middle
            mass += float(tool.get("mass", 0.0)) * held
        for hand, load, start, end in carried_loads(self.doc):
            # taken up over LOAD_RAMP from the start and put down over it to the end (the whole
            # window when shorter), as docs/metrics.md defines the carried centre of mass
            ramp = max(min(LOAD_RAMP, 0.5 * (end - start)), 1e-6)
            share = np.minimum(
                np.clip((self.time - start) / ramp, 0.0, 1.0),
                np.clip((end - self.time) / ramp, 0.0, 1.0),
            )
            held = share * ((self.time >= start) & (self.time <= end))
            total += load * held[:, None] * self.points[hand]
            mass += load * held
        return total / mass[:, None]


def carried_loads(doc: dict[str, Any]) -> list[tuple[str, float, float, float]]:
    """(hand, kg, start, end): a move with a load puts it in the hand from the move's start until
    that hand opens (a two-handed move shares it); the IR states the load on the goal's params."""
    segs = doc["segments"]
    end_of = doc["frames"]["time"][-1] if doc["frames"]["time"] else 0.0
    out = []
    for s in segs:
        goal = s.get("goal") or {}
        params = goal.get("params") or {}
        load = float(params.get("load") or 0.0)
        if s["kind"] != "TA" or load <= 0 or goal.get("effector") not in ("r_hand", "l_hand"):
            continue
        hand = goal["effector"]
        opens = [
            g["t_end"]
            for g in segs
            if g["track"] == hand
            and g["kind"] == "grip"
            and g["t_start"] >= s["t_start"]
            and (g["goal"].get("params") or {}).get("state") == "open"
        ]
        share = 0.5 if params.get("two_handed") else 1.0
        out.append((hand, load * share, s["t_start"], min(opens, default=end_of)))
    return out


# ------------------------------------------------------------------ geometry
def segment_distance(p1: Array, q1: Array, p2: Array, q2: Array) -> Array:
    """(T,) closest distance between segments p1q1 and p2q2, each (T, 3) (Ericson 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = (d1 * d1).sum(-1), (d2 * d2).sum(-1)
    f, c, b = (d2 * r).sum(-1), (d1 * r).sum(-1), (d1 * d2).sum(-1)
    a, e = np.maximum(a, 1e-12), np.maximum(e, 1e-12)
    denom = a * e - b * b
    s = np.where(denom > 1e-12, np.clip((b * f - c * e) / np.maximum(denom, 1e-12), 0, 1), 0.0)
    t = (b * s + f) / e
    s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
    t = np.clip(t, 0, 1)
    c1, c2 = p1 + s[:, None] * d1, p2 + t[:, None] * d2
    return np.linalg.norm(c1 - c2, axis=-1)


def hull(points: Array) -> Array:
    """Convex hull (counter-clockwise) of (N, 2) points, Andrew's monotone chain."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) <= 2:
        return np.asarray(pts)

    def cross(o: Any, a: Any, b: Any) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[Any] = []
    upper: list[Any] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-12:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-12:
            upper.pop()
        upper.append(p)
    return np.asarray(lower[:-1] + upper[:-1])


def margin(poly: Array, c: Array) -> float:
    """Signed distance (m) from ``c`` to the edge of a convex polygon: positive inside. A point or
    a segment has no inside: the margin is minus the distance to it."""
    if len(poly) == 0:
        return -math.inf
    if len(poly) == 1:
        return -float(np.linalg.norm(c - poly[0]))
    edges = [(poly[k], poly[(k + 1) % len(poly)]) for k in range(len(poly))]
    dists = []
    inside = len(poly) >= 3
    for a, b in edges:
        ab, ac = b - a, c - a
        t = float(np.clip(ac @ ab / max(ab @ ab, 1e-18), 0, 1))
        dists.append(float(np.linalg.norm(ac - t * ab)))
        if ab[0] * ac[1] - ab[1] * ac[0] < 0:
            inside = False
    return min(dists) if inside else -min(dists)


# ------------------------------------------------------------------ the measures
def final_goals(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """The goals a compile claims to reach: every TO, and every TA that no TO of the same
    effector continues (a reach with no approach point is all TA)."""
    tos = {(g["effector"], round(g["t_start"], 6)) for g in doc["goals"] if g["phase"] == "TO"}
    return [
        g
        for g in doc["goals"]
        if g["phase"] == "TO" or (g["effector"], round(g["t_end"], 6)) not in tos
    ]


@functools.cache
def gb10000() -> dict[tuple[str, int, str], float]:
    """GB 10000-88's table (mm), read from the data file mtlc ships (data, not mtlc code)."""
    table = {}
    for line in GB10000_CSV.read_text(encoding="utf-8").splitlines():
        if line.startswith("#") or not line.strip():
            continue
        sex, pct, name, value = line.split(",")[:4]
        if pct.isdigit():
            table[(sex, int(pct), name)] = float(value)
    return table


def body_capsules(doc: dict[str, Any]) -> tuple[dict[str, float], dict[str, float]]:
    """The radii (m) of docs/metrics.md's capsules for the compile's manikin: body parts (trunk,
    thigh) and limbs (forearm, hand), from its GB 10000-88 row (sex, percentile in the IR)."""
    m = doc["manikin"]
    if m["population"] != "gb10000_1988":
        raise ValueError(f"hands inside: no GB 10000-88 row for population {m['population']}")

    def mm(name: str) -> float:
        return gb10000()[(m["sex"], int(m["percentile"]), name)] / 1000.0

    parts = {"trunk": 0.5 * mm("chest_depth"), "thigh": 0.5 * mm("thigh_clearance_sitting")}
    limbs = {
        "forearm": FOREARM_OF_HAND_BREADTH * mm("hand_breadth"),
        "hand": HAND_OF_HAND_BREADTH * mm("hand_breadth"),
    }
    return parts, limbs


def report_lines(doc: dict[str, Any], t: float) -> set[int]:
    """The task lines a finding at time ``t`` may be reported at: those of the segments live at
    ``t``, else of the last one that ended (as docs/metrics.md says verify reports)."""
    segs = doc["segments"]
    live = [s for s in segs if s["t_start"] - 1e-6 <= t <= s["t_end"] + 1e-6]
    if not live:
        ended = sorted((s for s in segs if s["t_end"] <= t + 1e-6), key=lambda s: s["t_end"])
        live = ended[-1:]
    return {s["origin"]["line"] for s in live if s.get("origin")}


def body_inside(
    body: Body, diagnostics: list[dict[str, Any]]
) -> tuple[float, dict[str, Any] | None, bool]:
    """(depth, where, silent): how deep (m) the surface of a hand (wrist to one radius short of
    the fingertip) or forearm (elbow to wrist) goes into the trunk (pelvis to the mid-point of
    the sternoclavicular joints) or a thigh (hip to knee), each a capsule with its radius; and
    whether that depth, over ``INSIDE_TOL``, has no MT0514 at a line live at the deepest frame."""
    P = body.points
    parts, limbs = body_capsules(body.doc)
    sternum = 0.5 * (P["r_clavicle"] + P["l_clavicle"])
    bodies = [("trunk", P["pelvis"], sternum, parts["trunk"])] + [
        (f"{o}_thigh", P[f"{o}_hip"], P[f"{o}_knee"], parts["thigh"]) for o in ("r", "l")
    ]
    inside, inside_at = 0.0, None
    for side in ("r", "l"):
        wrist, tip = P[f"{side}_wrist"], P[f"{side}_fingertip"]
        along = (tip - wrist) / np.linalg.norm(tip - wrist, axis=-1, keepdims=True)
        arm = [
            (f"{side}_hand", wrist, tip - limbs["hand"] * along, limbs["hand"]),
            (f"{side}_forearm", P[f"{side}_elbow"], wrist, limbs["forearm"]),
        ]
        for lname, a, b, ra in arm:
            for bname, c, d, rb in bodies:
                depth = ra + rb - segment_distance(a, b, c, d)
                k = int(np.argmax(depth))
                if depth[k] > inside:
                    inside = float(depth[k])
                    inside_at = {"what": f"{lname} in {bname}", "t": float(body.time[k])}
    silent = False
    if inside > INSIDE_TOL and inside_at is not None:
        lines = report_lines(body.doc, inside_at["t"])
        file = body.doc["source"].get("file")
        named = {
            d["span"]["line"]
            for d in diagnostics
            if d["code"] == "MT0514" and d["span"].get("file") in (file, None)
        }
        silent = not (lines & named)
    return inside, inside_at, silent


def measure(doc: dict[str, Any], diagnostics: list[dict[str, Any]]) -> dict[str, Any]:
    """Every figure of the table for one compile's IR JSON and the diagnostics it printed."""
    body = Body.of(doc)
    T = len(body.time)
    ground = float(doc["scene"]["ground"])
    named = {
        (d["span"]["file"], d["span"]["line"])
        for d in diagnostics
        if not d["code"].startswith(UNRELATED)
    }
    # contact and silent misses
    contact, misses = 0.0, []
    for g in final_goals(doc):
        if g["effector"] not in body.points:
            continue
        k = body.frame_at(g["t_end"])
        err = float(np.linalg.norm(body.points[g["effector"]][k] - np.asarray(g["position"])))
        contact = max(contact, err)
        src = g["source"]
        if err > MISS_TOL and (src["file"], src["line"]) not in named:
            misses.append(
                {
                    "line": src["line"],
                    "effector": g["effector"],
                    "site": g["site"],
                    "t": g["t_end"],
                    "mm": round(err * 1000, 1),
                }
            )
    # penetration of every point (tool tips while held)
    lowest = np.full(T, np.inf)
    worst_point = ""
    for name, p in body.points.items():
        y = p[:, 1].copy()
        if name in body.tools:
            _, start, end = body.tools[name]
            y[(body.time < start) | (body.time > end)] = np.inf
        if np.min(y) < np.min(lowest):
            worst_point = name
        lowest = np.minimum(lowest, y)
    penetration = max(0.0, ground - float(np.min(lowest)))
    # the body floats when even its lowest point is off the floor (walking has no flight phase)
    hover = max(0.0, float(np.max(lowest)) - ground)
    hover_at = float(body.time[int(np.argmax(lowest))])
    # grip drift on parts that stay put
    drift, drift_at = 0.0, None
    loco = [s for s in doc["segments"] if s["kind"] == "locomotion"]
    for side in ("r", "l"):
        hand = f"{side}_hand"
        grips = sorted(
            (s for s in doc["segments"] if s["track"] == hand and s["kind"] == "grip"),
            key=lambda s: s["t_start"],
        )
        own = [
            s
            for s in doc["segments"]
            if s["track"] in (f"{side}_arm", hand) and s["kind"] != "grip"
        ]
        moves = sorted(s["t_start"] for s in own if s["kind"] in ("TA", "TO"))
        for k, g in enumerate(grips):
            if (g["goal"].get("params") or {}).get("state") != "closed":
                continue
            start = g["t_end"]
            later = [s["t_start"] for s in grips[k + 1 :] if s["t_start"] >= start]
            end = min([*later, *(t for t in moves if t >= start - 1e-9)], default=body.time[-1])
            window = (body.time >= start - 1e-9) & (body.time <= end + 1e-9)
            still = window & ~body.active(own) & ~body.active(loco)
            # a grip that takes its part somewhere before it opens (an arm goal that is not a
            # wrench's stroke, or a walk) carries it through the postures on the way
            opens = min(
                (s["t_start"] for s in grips[k + 1 :]
                 if (s["goal"].get("params") or {}).get("state") == "open"),
                default=np.inf,
            )  # fmt: skip
            takes = [
                s for s in [*own, *loco]
                if s["kind"] in ("TA", "TO", "locomotion")
                and "stroke" not in (s["goal"].get("params") or {})
                and g["t_start"] - 1e-9 <= s["t_start"] < opens - 1e-9
            ]  # fmt: skip
            if takes:
                postures = [
                    s for s in doc["segments"]
                    if s["kind"] == "posture" and s["track"] == "root"
                    and g["t_start"] - 1e-9 <= s["t_start"] < opens - 1e-9
                ]  # fmt: skip
                still &= ~body.active(postures)
            idx = np.flatnonzero(still)
            if len(idx) < 2:
                continue
            for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
                p = body.points[hand][run]
                d = float(np.max(np.linalg.norm(p - p[0], axis=-1)))
                if d > drift:
                    line = (g.get("origin") or {}).get("line")
                    drift_at = {"hand": hand, "line": line, "t": float(body.time[run[0]])}
                    drift = d
    # true static margin
    com = body.com()
    static = ~body.active(loco)
    goals_of: dict[str, list[Array]] = {"r_hand": [], "l_hand": []}
    for g in doc["goals"]:
        if g["effector"] in goals_of:
            goals_of[g["effector"]].append(np.asarray(g["position"], float))
    # a kneeling knee bears on its front, the lowest point of a sphere of half a knee's depth
    # about the knee's centre, over a patella's breadth across (docs/metrics.md, "Static
    # balance": ± KNEE_HALF_WIDTH along the knee's flexion axis; the IR has no point there)
    support_points = dict(body.points)
    knee_axis = {
        j["name"]: np.asarray(d["axis"], float)
        for j in doc["manikin"]["joints"]
        for d in j["dofs"]
        if d["name"].endswith("_knee_flex")
    }
    for side in ("r", "l"):
        R, p = body.world[f"{side}_knee"]
        front = p - [0.0, KNEE_DEPTH, 0.0]
        across = R @ knee_axis[f"{side}_knee"]
        for sign, tag in ((1.0, "a"), (-1.0, "b")):
            support_points[f"{side}_knee_front_{tag}"] = front + sign * KNEE_HALF_WIDTH * across
    names = list(support_points)
    ys = np.stack([support_points[n][:, 1] for n in names], 1)  # (T, N)
    xz = np.stack([support_points[n][:, [0, 2]] for n in names], 1)  # (T, N, 2)
    goal_d = {
        names.index(hand): np.min(
            np.linalg.norm(body.points[hand][:, None, :] - np.stack(targets)[None], axis=-1), 1
        )
        for hand, targets in goals_of.items()
        if targets
    }
    tools = [names.index(n) for n in body.tools]

    def worst(tol: float) -> tuple[float, Any, int]:
        """(margin, where, frames with no support) with points within ``tol`` touching."""
        floor_touch = ys <= ground + tol
        floor_touch[:, tools] = False
        worst_margin, margin_at, unsupported = math.inf, None, 0
        for k in np.flatnonzero(static):
            touch = floor_touch[k].copy()
            for col, d in goal_d.items():
                touch[col] |= d[k] <= tol
            if not touch.any():
                unsupported += 1
                continue
            m = margin(hull(xz[k, touch]), com[k, [0, 2]])
            if m < worst_margin:
                worst_margin = m
                margin_at = {
                    "t": float(body.time[k]),
                    "touch": [n for n, on in zip(names, touch, strict=True) if on],
                }
        return worst_margin, margin_at, unsupported

    worst_margin, margin_at, unsupported = worst(TOUCH_TOL)
    loose_margin, _, _ = worst(LOOSE_TOL)
    # hands and forearms inside the trunk or a thigh (docs/metrics.md, "hands inside the body")
    inside, inside_at, inside_silent = body_inside(body, diagnostics)
    # joint steps
    q = np.asarray(doc["frames"]["q"], float).reshape(T, -1)
    step, step_dof = 0.0, ""
    if T > 1:
        dq = np.abs(np.diff(q, axis=0))
        k = np.unravel_index(int(np.argmax(dq)), dq.shape)
        step, step_dof = math.degrees(float(dq[k])), doc["frames"]["dof_names"][k[1]]
    return {
        "goals": len(final_goals(doc)),
        "misses": misses,
        "contact_mm": contact * 1000,
        "penetration_mm": penetration * 1000,
        "penetration_point": worst_point,
        "hover_mm": hover * 1000,
        "hover_at": hover_at,
        "drift_mm": drift * 1000,
        "drift_at": drift_at,
        "margin_mm": worst_margin * 1000 if math.isfinite(worst_margin) else None,
        "margin_at": margin_at,
        "margin_10mm": loose_margin * 1000 if math.isfinite(loose_margin) else None,
        "unsupported_frames": unsupported,
        "inside_mm": inside * 1000,
        "inside_at": inside_at,
        "inside_silent": inside_silent,
        "step_deg": step,
        "step_dof": step_dof,
        **human.measure(doc, body),
    }


# ------------------------------------------------------------------ jobs
@dataclass(frozen=True)
class Job:
    """One compile: a source file with one manikin (``female-p5``)."""

    kind: str  # "example", "walk" (bench/walks), "procedure" (bench/procedures) or "generated"
    path: str
    manikin: str
    seed: int | None = None


def manikin_option(name: str) -> str:
    sex, pct = name.split("-p")
    return f"gb10000_1988:{sex}:{pct}"


def measure_folder(job: Job, out: Path, stdout: str, code: int) -> dict[str, Any]:
    """The row of one compile from the files it wrote in ``out`` and the JSON it printed."""
    try:
        diagnostics = json.loads(stdout)["diagnostics"]
    except (ValueError, KeyError):
        diagnostics = [
            {
                "code": "MT0900",
                "severity": "error",
                "message": stdout[:200],
                "span": {"file": job.path, "line": 0},
            }
        ]
    result: dict[str, Any] = {
        "job": job,
        "exit": code,
        "codes": [d["code"] for d in diagnostics],
        "tasks": [],
    }
    for ir in sorted(out.glob("*.ir.json")):
        doc = json.loads(ir.read_text(encoding="utf-8"))
        result["tasks"].append({"task": doc["source"]["task"], **measure(doc, diagnostics)})
    return result


def remeasure(folder: Path, sources: Path | None) -> list[dict[str, Any]]:
    """Rows of compiles kept with ``--keep`` (no compile: after a change of this bench)."""
    rows = []
    for sub in sorted(p for p in folder.iterdir() if (p / "diagnostics.json").is_file()):
        stem, manikin = sub.name.rsplit(".", 1)
        kind = "generated" if stem.startswith("gen_") else "example"
        base = sources if kind == "generated" and sources else ROOT / "examples"
        if kind == "example" and (ROOT / "bench" / "walks" / f"{stem}.mtask").is_file():
            kind, base = "walk", ROOT / "bench" / "walks"
        if kind == "example" and (ROOT / "bench" / "procedures" / f"{stem}.mtask").is_file():
            kind, base = "procedure", ROOT / "bench" / "procedures"
        job = Job(kind, str(base / f"{stem}.mtask"), manikin)
        stdout = (sub / "diagnostics.json").read_text(encoding="utf-8")
        rows.append(measure_folder(job, sub, stdout, 0))
    return rows


def run_job(job: Job, keep: Path | None = None) -> dict[str, Any]:
    """Compile through the CLI's entry point in this worker, then measure the files it wrote
    (kept in ``keep``/STEM.MANIKIN/ with the diagnostics when given)."""
    from mtlc.cli import main as mtlc_main

    if keep is None:
        out = Path(tempfile.mkdtemp(prefix="mtlc-motion-"))
    else:
        out = keep / f"{Path(job.path).stem}.{job.manikin}"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir(parents=True)
    buf = io.StringIO()
    try:
        argv = [
            "compile",
            job.path,
            "--manikin",
            manikin_option(job.manikin),
            "--target",
            "ir",
            "-o",
            str(out),
            "--format",
            "json",
        ]
        with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
            code = mtlc_main(argv)
        if keep is not None:
            (out / "diagnostics.json").write_text(buf.getvalue(), encoding="utf-8")
        result = measure_folder(job, out, buf.getvalue(), code)
        return result
    except Exception as exc:  # a bench bug or a compile that cannot be read: a row, not a crash
        return {
            "job": job,
            "exit": -1,
            "codes": [],
            "tasks": [],
            "error": f"{type(exc).__name__}: {exc}",
        }
    finally:
        if keep is None:
            shutil.rmtree(out, ignore_errors=True)


# ------------------------------------------------------------------ the table
GOALS = {
    "silent misses": "0",
    "penetration mm": "<= 1 (examples)",
    "floating mm": "<= 2 (something touches)",
    "grip drift mm": "<= 1 (examples)",
    "contact error mm": "<= 1 or a diagnostic",
    "static margin mm": ">= 0 or MT0502",
    "margin (10 mm) mm": "(touch within 10 mm, mtlc's tolerance)",
    "hands inside mm": "<= 1 (examples) or MT0514",
    "joint step deg": "(smooth; no goal)",
}


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def table(rows: list[dict[str, Any]], label: str) -> list[str]:
    """Lines of the summary table of one group of compiles."""
    tasks = [t for r in rows for t in r["tasks"]]
    lines = [f"\n## {label}: {len(rows)} compiles, {len(tasks)} task outputs"]
    failed = [r for r in rows if not r["tasks"]]
    codes = Counter(c for r in rows for c in r["codes"])
    lines.append(
        f"compiles without output: {len(failed)}; diagnostics raised: "
        + (", ".join(f"{c} x{n}" for c, n in sorted(codes.items())) or "none")
    )
    lines.append(f"{'figure':<20} {'median':>9} {'p95':>9} {'worst':>9} {'cases over':>16}   goal")
    n_goals = sum(t["goals"] for t in tasks)
    n_miss = sum(len(t["misses"]) for t in tasks)
    cases = sum(1 for t in tasks if t["misses"])
    lines.append(
        f"{'silent misses':<20} {'':>9} {'':>9} {n_miss:>9} {f'{cases} tasks':>16}   "
        f"{GOALS['silent misses']}  (of {n_goals} goals)"
    )

    def row(name: str, key: str, limit: float, worse_below: bool = False) -> None:
        vals = [t[key] for t in tasks if t[key] is not None]
        if not vals:
            lines.append(f"{name:<20} {'-':>9}")
            return
        worst = min(vals) if worse_below else max(vals)
        over = sum(1 for v in vals if (v < limit if worse_below else v > limit))
        cmp = "<" if worse_below else ">"
        mid = _pct(vals, 50)
        p95 = _pct(vals, 5 if worse_below else 95)
        lines.append(
            f"{name:<20} {mid:>9.2f} {p95:>9.2f} {worst:>9.2f} "
            f"{f'{over} {cmp} {limit:g}':>16}   {GOALS[name]}"
        )

    row("contact error mm", "contact_mm", 1.0)
    row("penetration mm", "penetration_mm", 1.0)
    row("floating mm", "hover_mm", 2.0)
    row("grip drift mm", "drift_mm", 1.0)
    row("static margin mm", "margin_mm", 0.0, worse_below=True)
    row("margin (10 mm) mm", "margin_10mm", 0.0, worse_below=True)
    row("hands inside mm", "inside_mm", INSIDE_TOL * 1000)
    silent = sum(1 for t in tasks if t.get("inside_silent"))
    lines.append(f"hands inside over {INSIDE_TOL * 1000:g} mm with no MT0514 at the line: {silent}")
    row("joint step deg", "step_deg", 10.0)
    unsup = sum(1 for t in tasks if t["unsupported_frames"])
    lines.append(f"tasks with static frames where nothing touches: {unsup}")
    return lines + human.table(tasks)


def reproducer(job: Job) -> str:
    return (
        f"python -m mtlc compile {job.path} --manikin {manikin_option(job.manikin)} "
        "--target ir --metrics"
    )


def worst_cases(rows: list[dict[str, Any]], n: int) -> list[str]:
    """The ``n`` worst compiles for each figure, with what and where."""
    out = ["\n## worst cases"]
    flat = [(r["job"], t) for r in rows for t in r["tasks"]]
    specs = [
        (
            "silent miss",
            lambda t: max((m["mm"] for m in t["misses"]), default=0.0),
            lambda t: "; ".join(
                f"line {m['line']} {m['effector']}->{m['site']} {m['mm']} mm @{m['t']:.2f}s"
                for m in t["misses"][:3]
            ),
        ),
        ("penetration", lambda t: t["penetration_mm"], lambda t: t["penetration_point"]),
        ("floating", lambda t: t["hover_mm"], lambda t: f"at {t['hover_at']:.2f} s"),
        ("grip drift", lambda t: t["drift_mm"], lambda t: str(t["drift_at"])),
        (
            "static margin",
            lambda t: -(t["margin_mm"] if t["margin_mm"] is not None else 0.0),
            lambda t: f"margin {t['margin_mm']:.1f} mm at {t['margin_at']}",
        ),
        (
            "hands inside",
            lambda t: t["inside_mm"],
            lambda t: f"{t['inside_at']}{' SILENT' if t.get('inside_silent') else ''}",
        ),
        ("joint step", lambda t: t["step_deg"], lambda t: t["step_dof"]),
        *human.WORST,
    ]
    for name, key, what in specs:
        ranked = sorted(flat, key=lambda jt: -key(jt[1]))[:n]
        ranked = [jt for jt in ranked if key(jt[1]) > 0]
        out.append(f"\n### {name}")
        for job, t in ranked:
            out.append(f"{abs(key(t)):8.1f}  {Path(job.path).name} {job.manikin}  {what(t)}")
            out.append(f"          {reproducer(job)}")
    errors = [r for r in rows if r.get("error") or r["exit"] not in (0, 1)]
    internal = [r for r in rows if "MT0900" in r["codes"]]
    out.append(f"\n### bench errors / MT0900: {len(errors)} / {len(internal)}")
    for r in (errors + internal)[:n]:
        out.append(f"  {r['job'].path} {r['job'].manikin} exit {r['exit']} {r.get('error', '')}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--generated", type=int, default=200, help="generated procedures (200)")
    parser.add_argument("--seed0", type=int, default=0, help="first seed (0)")
    parser.add_argument("--steps", default="3:8", help="task-level steps per procedure, MIN:MAX")
    parser.add_argument(
        "--manikins",
        default="female-p5,male-p95",
        help="manikins of the generated procedures (female-p5,male-p95)",
    )
    parser.add_argument(
        "--examples",
        default="all",
        help="'all', 'none' or a comma list of example stems (with all 14 manikins)",
    )
    parser.add_argument("--example-manikins", default="all", help="'all' 14 or a comma list")
    parser.add_argument(
        "--walks",
        action="store_true",
        help="also compile bench/walks/*.mtask with each of --example-manikins",
    )
    parser.add_argument(
        "--procedures",
        action="store_true",
        help="also compile bench/procedures/*.mtask with each of --example-manikins",
    )
    parser.add_argument("--workers", type=int, default=2, help="worker processes (2)")
    parser.add_argument("--save", type=Path, help="keep the generated procedures in this folder")
    parser.add_argument("--worst", type=int, default=8, help="worst cases listed per figure (8)")
    parser.add_argument("--json", type=Path, help="also write every row as JSON here")
    parser.add_argument(
        "--keep", type=Path, help="keep each compile's IR JSON and diagnostics here"
    )
    parser.add_argument(
        "--remeasure", type=Path, help="measure a --keep folder again instead of compiling"
    )
    args = parser.parse_args(argv)
    if args.remeasure is not None and not args.remeasure.is_dir():
        parser.error(f"--remeasure: {args.remeasure} is not a --keep folder")

    folder = args.save or Path(tempfile.mkdtemp(prefix="mtlc-generated-"))
    lo, hi = (int(x) for x in args.steps.split(":"))
    jobs: list[Job] = []
    if args.examples != "none":
        picked = (
            EXAMPLES
            if args.examples == "all"
            else [p for p in EXAMPLES if p.stem in args.examples.split(",")]
        )
        mans = (
            MANIKINS if args.example_manikins == "all" else tuple(args.example_manikins.split(","))
        )
        jobs += [Job("example", str(p.relative_to(ROOT)), m) for p in picked for m in mans]
    if args.walks:
        mans = (
            MANIKINS if args.example_manikins == "all" else tuple(args.example_manikins.split(","))
        )
        jobs += [Job("walk", str(p.relative_to(ROOT)), m) for p in WALKS for m in mans]
    if args.procedures:
        mans = (
            MANIKINS if args.example_manikins == "all" else tuple(args.example_manikins.split(","))
        )
        jobs += [Job("procedure", str(p.relative_to(ROOT)), m) for p in PROCEDURES for m in mans]
    gen_manikins = [m for m in args.manikins.split(",") if m]
    for seed in range(args.seed0, args.seed0 + args.generated):
        path = generate(seed, lo, hi).write(folder)
        jobs += [Job("generated", str(path), m, seed) for m in gen_manikins]
    print(
        f"{len(jobs)} compiles in {args.workers} workers; generated procedures in {folder}",
        file=sys.stderr,
        flush=True,
    )
    rows: list[dict[str, Any]] = []
    if args.remeasure:
        rows, jobs = remeasure(args.remeasure, args.save), []
    ctx = multiprocessing.get_context("fork" if sys.platform != "win32" else "spawn")
    with ctx.Pool(args.workers, maxtasksperchild=25) as pool:
        work = functools.partial(run_job, keep=args.keep)
        for k, row in enumerate(pool.imap_unordered(work, jobs), 1):
            rows.append(row)
            if k % 20 == 0 or k == len(jobs):
                print(f"  {k}/{len(jobs)}", file=sys.stderr, flush=True)
    rows.sort(key=lambda r: (r["job"].kind, r["job"].path, r["job"].manikin))
    lines = [f"# bench/motion.py {' '.join(argv if argv is not None else sys.argv[1:])}"]
    for kind, label in (
        ("example", "examples x manikins"),
        ("walk", "bench/walks x manikins"),
        ("procedure", "bench/procedures x manikins"),
        ("generated", "generated procedures"),
    ):
        group = [r for r in rows if r["job"].kind == kind]
        if group:
            lines += table(group, label)
    lines += worst_cases(rows, args.worst)
    print("\n".join(lines))
    if args.json:
        args.json.write_text(
            json.dumps([{**r, "job": r["job"].__dict__} for r in rows], indent=1, default=str),
            encoding="utf-8",
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
