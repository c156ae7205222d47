"""Does the motion move like a person? Issue 19's figures, measured on a compile's output frames.

Used by bench/motion.py (each compile's row gains these keys; its table prints them beside the
issue's goals). Like motion.py, it reads the IR JSON only and uses no mtlc code: the positions come
from motion.py's forward kinematics of the file (``Body``). Definitions (docs/testing.md):

* joint step: the largest change of one degree of freedom between two consecutive output frames,
  frame 0 included, and the root's turn (the angle of its relative rotation); the wrist and the
  forearm's pronation during a fastener turn (``turn_fastener``) are judged apart (their goal is
  looser). Peak joint speed is that step over the frame interval.
* reach: one movement of an effector (hand or tool tip) to a goal: from the start of its approach
  (TA) to the end of the goal it claims (the TO that continues the TA, or the TA itself).
  Reaches shorter than 4 frames or moving less than 1 cm are not judged (too few samples for a
  jerk).
* stroke (a wrench's or ratchet's TO with a ``stroke`` number): not one reach but the movements
  it is made of, each from rest to rest (a reciprocating movement that stops at each reversal is
  a series of discrete movements: Hogan & Sternad 2007, "On rhythmic and discrete movements",
  Exp Brain Res 181:13-30): the seat, the swing (the hand turns the handle through the swing
  angle) and the return (lift off, swing back, re-seat), at the times the stroke's
  ``result.phases`` records (older IR: 10 %, 60 % of the stroke). Each is judged by the hand
  that holds the handle: in the swing the tip only turns on the fastener, the hand is what
  moves. Each is judged on the frames inside it (the next movement starts where it ends); the
  return's contact speed is the tool tip's, where it comes back onto the fastener, over the
  frame interval that ends at the first frame at or after the stroke's end.
* LDLJ: log dimensionless jerk of the effector's path, -ln((t2 - t1)^3 / v_peak^2 * integral of
  |jerk|^2 dt) (Balasubramanian, Melendez-Calderon, Roby-Brami & Burdet 2015, "On the analysis
  of movement smoothness", J NeuroEng Rehabil 12:112), jerk by third differences at the output
  rate. A minimum-jerk reach scores -5.3; keys joined by straight lines about -13.6.
* velocity peaks: maxima of the effector's speed whose prominence is at least 10 % of the reach's
  peak speed (the speed is taken as zero just before and after the reach, so a movement that
  starts or ends at speed shows its peak at the edge).
* contact speed: the effector's speed over the last frame interval before the first output frame
  at or after the goal's end (the frame where contact is claimed); a stroke's seat and swing
  make no contact (the tip stays on), its return is judged by the tip.
* gait, over each locomotion segment: a foot swings while its lowest contact point is more than
  5 mm above the floor; steps are the swing
  phases; cadence = steps / the walk's duration (min^-1); swing time the length of each swing
  phase; pelvis excursion = highest minus lowest pelvis height during the walk; ankle speed the
  fastest an ankle moves during it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

Array = np.ndarray

TURN_DOFS = ("wrist_flex", "wrist_dev", "elbow_pro")  # judged apart during a fastener turn
MIN_REACH_FRAMES = 4
MIN_REACH_PATH = 0.01  # m
PEAK_PROMINENCE = 0.10  # of the reach's peak speed
SWING_HEIGHT = 5e-3  # m: a foot whose lowest point is this far above the floor swings
CARRY_EDGE = 0.6  # s: a carried walk's trunk is judged this far in from its ends (the ramps)


def _angle_between(qa: Array, qb: Array) -> Array:
    """(T,) angles of the rotations between two (T, 4) unit quaternion tracks (w, x, y, z)."""
    dot = np.abs(np.sum(qa * qb, axis=1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def _in_windows(time: Array, windows: list[tuple[float, float]]) -> Array:
    on = np.zeros(len(time), bool)
    for a, b in windows:
        on |= (time >= a - 1e-9) & (time <= b + 1e-9)
    return on


def joint_steps(doc: dict[str, Any], time: Array) -> dict[str, Any]:
    """The largest one-frame step of any dof (outside and inside fastener turns) and its speed."""
    f = doc["frames"]
    T = len(time)
    names = list(f["dof_names"])
    if T < 2:
        return {"step_max_deg": 0.0, "step_max_dof": "", "turn_step_deg": 0.0, "steps_over_12": 0}
    q = np.asarray(f["q"], float).reshape(T, -1)
    steps = np.degrees(np.abs(np.diff(q, axis=0)))  # (T-1, D), step k from frame k to k+1
    root = np.degrees(
        _angle_between(
            np.asarray(f["root_rotation"], float)[:-1], np.asarray(f["root_rotation"], float)[1:]
        )
    )
    steps = np.concatenate([steps, root[:, None]], axis=1)
    names.append("root_turn")
    turns = [
        (s["t_start"], s["t_end"])
        for s in doc["segments"]
        if str(s.get("path", "")).endswith("turn_fastener")
    ]
    # a step belongs to a turn when either of its frames does
    in_turn = _in_windows(time, turns)
    step_in_turn = in_turn[:-1] | in_turn[1:]
    turn_cols = np.array([any(n.endswith(d) for d in TURN_DOFS) for n in names])
    loose = step_in_turn[:, None] & turn_cols[None, :]
    strict = np.where(loose, 0.0, steps)
    k, d = np.unravel_index(int(np.argmax(strict)), strict.shape)
    dt = float(np.median(np.diff(time)))
    return {
        "step_max_deg": float(strict[k, d]),
        "step_max_dof": f"{names[d]} @{time[k]:.2f}s",
        "speed_max_dps": float(strict[k, d]) / dt,
        "turn_step_deg": float(np.max(np.where(loose, steps, 0.0))),
        "steps_over_12": int(np.sum(np.max(strict, axis=1) > 12.0)),
    }


def _ldlj(p: Array, dt: float) -> float:
    """Log dimensionless jerk of a (N, 3) path sampled every ``dt`` seconds, at rest before and
    after it (a reach that starts or stops at speed pays for it in jerk)."""
    duration = dt * (len(p) - 1)
    p = np.concatenate([p[:1], p[:1], p, p[-1:], p[-1:]])
    v = np.diff(p, axis=0) / dt
    speed = np.linalg.norm(v, axis=1)
    jerk = np.diff(p, n=3, axis=0) / dt**3
    v_peak = float(np.max(speed))
    integral = float(np.sum(np.sum(jerk**2, axis=1)) * dt)
    if v_peak <= 0.0 or integral <= 0.0:
        return 0.0
    return -math.log(duration**3 / v_peak**2 * integral)


def _peaks(speed: Array) -> int:
    from scipy.signal import find_peaks

    padded = np.concatenate([[0.0], speed, [0.0]])
    top = float(np.max(speed))
    if top <= 0.0:
        return 0
    found, _ = find_peaks(padded, prominence=PEAK_PROMINENCE * top)
    return len(found)


STROKE_SHARES = {"seat": (0.0, 0.1), "swing": (0.1, 0.6), "return": (0.6, 1.0)}  # older IR


def stroke_movements(g: dict[str, Any], seg: dict[str, Any]) -> list[dict[str, Any]]:
    """A wrench or ratchet stroke's movements, each judged on its own (docs/testing.md): the
    seat and the swing by the hand that swings the handle, from rest to rest, and the return
    (lift off, swing back, re-seat) by the hand, its contact speed by the tool's tip where it
    comes back onto the fastener. The phases are the stroke's ``result.phases`` (times); IR
    written before they were recorded is split at the shares its stroke plan used."""
    phases = (seg.get("result") or {}).get("phases")
    if not phases:
        a, b = float(g["t_start"]), float(g["t_end"])
        phases = {k: [a + (b - a) * x, a + (b - a) * y] for k, (x, y) in STROKE_SHARES.items()}
    src = g.get("source") or {}
    what = str(src.get("path", "")).split(" > ")[-1]
    hand = f"{g['effector'][0]}_hand"
    return [
        {
            "effector": hand,
            "start": float(phases[name][0]),
            "end": float(phases[name][1]),
            "line": src.get("line"),
            "what": f"{what} stroke {name}",
            "contact": g["effector"] if name == "return" else None,
            "inside": True,
        }
        for name in ("seat", "swing", "return")
    ]


def reach_windows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """Each movement to a claimed goal: (effector, start, end, line, what, contact), the
    effector whose speed is judged at contact (None: the movement makes none)."""
    goals = doc["goals"]
    segs = [s for s in doc.get("segments", []) if s["kind"] in ("TA", "TO")]
    if len(segs) != len(goals):
        segs = [{} for _ in goals]
    out = []
    for g, seg in zip(goals, segs, strict=True):
        if "stroke" in ((seg.get("goal") or {}).get("params") or {}):
            out += stroke_movements(g, seg)
            continue
        ends_in_to = any(
            h["phase"] == "TO"
            and h["effector"] == g["effector"]
            and abs(h["t_start"] - g["t_end"]) < 1e-6
            for h in goals
        )
        if g["phase"] == "TA" and ends_in_to:
            continue  # judged with the TO that continues it
        start = g["t_start"]
        if g["phase"] == "TO":
            for h in goals:
                if (
                    h["phase"] == "TA"
                    and h["effector"] == g["effector"]
                    and abs(h["t_end"] - g["t_start"]) < 1e-6
                ):
                    start = h["t_start"]
        src = g.get("source") or {}
        out.append(
            {
                "effector": g["effector"],
                "start": float(start),
                "end": float(g["t_end"]),
                "line": src.get("line"),
                "what": str(src.get("path", "")).split(" > ")[-1],
                "contact": g["effector"],
            }
        )
    return out


def reaches(doc: dict[str, Any], body: Any) -> dict[str, Any]:
    """LDLJ, velocity peaks and contact speed of every judged reach."""
    time = body.time
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 1.0
    judged = []
    for r in reach_windows(doc):
        if r["effector"] not in body.points:
            continue
        a = int(np.searchsorted(time, r["start"] - 1e-9))
        after = min(int(np.searchsorted(time, r["end"] - 1e-9)), len(time) - 1)
        # a stroke's phases follow one another: the frame after one is the next one's
        b = int(np.searchsorted(time, r["end"] + 1e-9)) - 1 if r.get("inside") else after
        if b - a + 1 < MIN_REACH_FRAMES:
            continue
        p = body.points[r["effector"]][a : b + 1]
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        if float(np.sum(steps)) < MIN_REACH_PATH:
            continue
        speed = steps / dt
        contact = None
        if r["contact"] in body.points:
            tip = body.points[r["contact"]]
            contact = float(np.linalg.norm(tip[after] - tip[after - 1])) / dt * 100.0
        judged.append(
            {
                **r,
                "ldlj": _ldlj(p, dt),
                "peaks": _peaks(speed),
                "contact_cms": contact,
                "peak_ms": float(np.max(speed)),
            }
        )
    if not judged:
        return {
            "reaches": 0,
            "ldlj_min": None,
            "ldlj_ok": 0,
            "multi_peak": 0,
            "contact_cms_max": None,
            "reach_worst": None,
        }
    ldlj = [j["ldlj"] for j in judged]
    worst = min(judged, key=lambda j: j["ldlj"])
    touching = [j for j in judged if j["contact_cms"] is not None]
    fastest = max(touching, key=lambda j: j["contact_cms"], default=None)
    strokes = [j for j in judged if " stroke " in j["what"]]
    return {
        "reaches": len(judged),
        "ldlj_min": min(ldlj),
        "ldlj_all": ldlj,
        "ldlj_ok": sum(1 for v in ldlj if v >= -7.0),
        "multi_peak": sum(1 for j in judged if j["peaks"] > 1),
        "peaks_all": [j["peaks"] for j in judged],
        "contact_cms_max": fastest["contact_cms"] if fastest else None,
        "contact_all": [j["contact_cms"] for j in touching],
        "stroke_ldlj_all": [j["ldlj"] for j in strokes],
        "stroke_peaks_all": [j["peaks"] for j in strokes],
        "stroke_contact_all": [j["contact_cms"] for j in strokes if j["contact_cms"] is not None],
        "reach_worst": (
            f"line {worst['line']} {worst['what']} {worst['effector']} "
            f"@{worst['start']:.2f}-{worst['end']:.2f}s LDLJ {worst['ldlj']:.1f}, "
            f"{worst['peaks']} peaks"
            + (
                f"; contact {fastest['contact_cms']:.1f} cm/s at line "
                f"{fastest['line']} {fastest['what']} @{fastest['end']:.2f}s"
                if fastest
                else ""
            )
        ),
    }


def _runs(mask: Array) -> list[tuple[int, int]]:
    """(first, last) frame index of each run of True."""
    out, start = [], None
    for k, on in enumerate(mask):
        if on and start is None:
            start = k
        elif not on and start is not None:
            out.append((start, k - 1))
            start = None
    if start is not None:
        out.append((start, len(mask) - 1))
    return out


def gait(doc: dict[str, Any], body: Any) -> dict[str, Any]:
    """Cadence, swing time, pelvis excursion and ankle speed of each walk."""
    time = body.time
    ground = float(doc["scene"]["ground"])
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 1.0
    walks = [
        (float(s["t_start"]), float(s["t_end"]))
        for s in doc["segments"]
        if s["kind"] == "locomotion" and s["t_end"] - s["t_start"] > dt
    ]
    contacts = {c["name"] for c in doc["manikin"]["contact_points"]}
    cadences, swings, excursions, ankle = [], [], [], 0.0
    worst = None
    for a_t, b_t in walks:
        a = int(np.searchsorted(time, a_t - 1e-9))
        b = min(int(np.searchsorted(time, b_t - 1e-9)), len(time) - 1)
        if b - a < 2:
            continue
        steps = 0
        for side in ("r", "l"):
            ank = body.points[f"{side}_ankle"][a : b + 1]
            speed3 = np.linalg.norm(np.diff(ank, axis=0), axis=1) / dt
            ankle = max(ankle, float(np.max(speed3)) if len(speed3) else 0.0)
            feet = [n for n in contacts if n.startswith(f"{side}_")]
            low = np.min(np.stack([body.points[n][a : b + 1, 1] for n in feet]), axis=0)
            swing = low - ground > SWING_HEIGHT
            for s0, s1 in _runs(swing):
                steps += 1
                swings.append((s1 - s0 + 1) * dt)
        duration = b_t - a_t
        cad = 60.0 * steps / duration if steps else 0.0
        cadences.append(cad)
        pel = body.points["pelvis"][a : b + 1, 1]
        exc = float(np.max(pel) - np.min(pel))
        excursions.append(exc)
        if worst is None or cad > worst[0]:
            worst = (cad, f"{steps} steps in {duration:.2f} s @{a_t:.2f}s")
    if not walks:
        return {
            "walks": 0,
            "cadence_max": None,
            "swing_min": None,
            "pelvis_cm": None,
            "ankle_ms": None,
            "walk_worst": None,
        }
    return {
        "walks": len(walks),
        "cadence_max": max(cadences) if cadences else None,
        "cadence_min": min(cadences) if cadences else None,
        "swing_min": min(swings) if swings else None,
        "pelvis_cm": 100.0 * max(excursions) if excursions else None,
        "ankle_ms": ankle,
        "walk_worst": worst[1] if worst else None,
    }


def _closed_at(doc: dict[str, Any], hand: str, t: float) -> bool:
    """Whether the hand's last grip event before ``t`` closed it (the IR's grip segments)."""
    grips = sorted(
        (s for s in doc["segments"] if s["track"] == hand and s["kind"] == "grip"),
        key=lambda s: s["t_start"],
    )
    before = [g for g in grips if g["t_start"] < t - 1e-9]
    return bool(before) and (before[-1].get("goal") or {}).get("params", {}).get("state") != "open"


def carried_trunk(doc: dict[str, Any], time: Array) -> dict[str, Any]:
    """The trunk's lean (lumbar plus thorax flexion, degrees, from the frames' angles) in the
    middle of each walk that starts with a hand closed on a part (``CARRY_EDGE`` in from each
    end, its median): people walk upright with a load (issue 19: "a carried load is held near
    the body while walking"). The output's largest, and where."""
    frames = doc["frames"]
    names = frames["dof_names"]
    if "lumbar_flex" not in names or "thorax_flex" not in names:
        return {"carried_walks": 0, "carried_trunk_deg": None, "carried_trunk_at": None}
    q = np.asarray(frames["q"], float)
    lean = np.degrees(q[:, names.index("lumbar_flex")] + q[:, names.index("thorax_flex")])
    worst: tuple[float, str] | None = None
    count = 0
    for s in doc["segments"]:
        if s["kind"] != "locomotion":
            continue
        a, b = float(s["t_start"]), float(s["t_end"])
        middle = (time >= a + CARRY_EDGE) & (time <= b - CARRY_EDGE)
        if not middle.any() or not any(_closed_at(doc, h, a + 1e-6) for h in ("r_hand", "l_hand")):
            continue
        count += 1
        value = float(np.median(np.abs(lean[middle])))
        if worst is None or value > worst[0]:
            worst = (value, f"walk @{a:.2f}-{b:.2f}s")
    return {
        "carried_walks": count,
        "carried_trunk_deg": worst[0] if worst else None,
        "carried_trunk_at": worst[1] if worst else None,
    }


def measure(doc: dict[str, Any], body: Any) -> dict[str, Any]:
    """Every issue-19 figure of one compile."""
    return {
        **joint_steps(doc, body.time),
        **reaches(doc, body),
        **gait(doc, body),
        **carried_trunk(doc, body.time),
    }


# ------------------------------------------------------------------ the table
def _stats(vals: list[float]) -> tuple[float, float, float, float]:
    a = np.asarray(vals, float)
    return float(np.median(a)), float(np.percentile(a, 5)), float(np.percentile(a, 95)), len(a)


def _movement_rows(tasks: list[dict[str, Any]], label: str, prefix: str) -> list[str]:
    """LDLJ, velocity peaks and contact speed rows of the movements under ``prefix`` keys."""
    every = [v for t in tasks for v in t.get(f"{prefix}ldlj_all", [])]
    if not every:
        return []
    share = sum(1 for v in every if v >= -7.0) / len(every)
    peaks = [p for t in tasks for p in t.get(f"{prefix}peaks_all", [])]
    speeds = [v for t in tasks for v in t.get(f"{prefix}contact_all", [])]
    lines = [
        f"{label + ' LDLJ':<24} {float(np.median(every)):>8.2f} "
        f"{float(np.percentile(every, 5)):>8.2f} {float(np.percentile(every, 95)):>8.2f} "
        f"{min(every):>8.2f} {f'{sum(1 for v in every if v < -8.0)} of {len(every)}':>16}   "
        f">= -8 all, >= -7 for 90 % (now {100 * share:.0f} %)",
        f"{label + ' peaks':<24} {float(np.median(peaks)):>8.0f} {'':>8} "
        f"{float(np.percentile(peaks, 95)):>8.0f} {max(peaks):>8d} "
        f"{f'{sum(1 for p in peaks if p > 1)} of {len(peaks)}':>16}   1",
    ]
    if speeds:
        lines.append(
            f"{label + ' contact cm/s':<24} {float(np.median(speeds)):>8.2f} {'':>8} "
            f"{float(np.percentile(speeds, 95)):>8.2f} {max(speeds):>8.2f} "
            f"{f'{sum(1 for v in speeds if v > 5.0)} of {len(speeds)}':>16}   <= 5"
        )
    return lines


def table(tasks: list[dict[str, Any]]) -> list[str]:
    """Lines of issue 19's figures over a group of task outputs, each beside its goal."""
    lines = [
        f"{'human motion (issue 19)':<24} {'median':>8} {'p5':>8} {'p95':>8} {'worst':>8} "
        f"{'cases over':>16}   goal"
    ]

    def row(
        name: str,
        key: str,
        goal: str,
        lo: float = -math.inf,
        hi: float = math.inf,
        worse_below: bool = False,
    ) -> None:
        vals = [float(t[key]) for t in tasks if t.get(key) is not None]
        if not vals:
            lines.append(f"{name:<24} {'-':>8}")
            return
        mid, p5, p95, _ = _stats(vals)
        worst = min(vals) if worse_below else max(vals)
        over = sum(1 for v in vals if v < lo or v > hi)
        lines.append(
            f"{name:<24} {mid:>8.2f} {p5:>8.2f} {p95:>8.2f} {worst:>8.2f} "
            f"{f'{over} of {len(vals)}':>16}   {goal}"
        )

    row("joint step deg", "step_max_deg", "<= 12 (frame 0 included)", hi=12.0)
    row("turn wrist step deg", "turn_step_deg", "<= 20 (fastener turns)", hi=20.0)
    row("peak joint speed deg/s", "speed_max_dps", "<= 360", hi=360.0)
    for label, prefix in (("reach", ""), ("stroke move", "stroke_")):
        lines += _movement_rows(tasks, label, prefix)
    row("cadence max /min", "cadence_max", "90-125", lo=90.0, hi=125.0)
    row("cadence min /min", "cadence_min", "90-125", lo=90.0, hi=125.0, worse_below=True)
    row("swing min s", "swing_min", ">= 0.35", lo=0.35, worse_below=True)
    row("pelvis excursion cm", "pelvis_cm", "<= 6", hi=6.0)
    row("ankle speed m/s", "ankle_ms", "<= 5", hi=5.0)
    row("carried walk trunk deg", "carried_trunk_deg", "<= 10 (upright; no goal)", hi=10.0)
    return lines


WORST = (
    ("joint step (issue 19)", lambda t: t.get("step_max_deg") or 0.0, lambda t: t["step_max_dof"]),
    ("reach LDLJ", lambda t: -(t.get("ldlj_min") or 0.0), lambda t: t["reach_worst"]),
    ("cadence", lambda t: t.get("cadence_max") or 0.0, lambda t: t["walk_worst"]),
    (
        "carried walk trunk",
        lambda t: t.get("carried_trunk_deg") or 0.0,
        lambda t: t["carried_trunk_at"],
    ),
)
