"""How far a part held in both hands is squeezed or stretched while it is moved (issue 19).

    python bench/two_hands.py KEEP_DIR [KEEP_DIR_AFTER]

Reads the IR JSON that ``bench/motion.py --keep KEEP_DIR`` kept (no compile) and, with
motion.py's own forward kinematics of the file (no mtlc code), measures on the output frames
every two-handed carried move: a TA or TO of both arms with ``two_handed`` that starts while
both hands are closed on one two-handed part that both reached within 1 mm (verify's rule;
from the later close of the two grips until the earlier open). The
figure is max |d(t) - d(grip)| in mm, d the distance between the hands, d(grip) its value at the
first output frame at or after the later hand closed; beside it the largest change of one joint
between two output frames inside the move (deg). With two folders it prints both side by side,
per compile, and the totals.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from motion import Body

EPS = 1e-9
REACHED = 1e-3  # m: a hand further than this from the part at its grasp does not hold it


def _held_part(doc: dict[str, Any], arm: str, closes: float) -> str:
    """The two-handed site the arm's last TO before ``closes`` reached within 1 mm ("" when
    none: a hand that fell short of the part does not hold it; verify's rule)."""
    reach = max(
        (s for s in doc["segments"]
         if s["track"] == arm and s["kind"] == "TO" and s["t_end"] <= closes + EPS),
        key=lambda s: s["t_end"],
        default=None,
    )  # fmt: skip
    if reach is None:
        return ""
    goal = reach.get("goal") or {}
    if not (goal.get("params") or {}).get("two_handed") or not goal.get("site"):
        return ""
    distance = (reach.get("result") or {}).get("distance")
    return str(goal["site"]) if distance is not None and distance <= REACHED else ""


def _closed_spans(doc: dict[str, Any], hand: str) -> list[tuple[float, float, str]]:
    grips = sorted(
        (s for s in doc["segments"] if s["track"] == hand and s["kind"] == "grip"),
        key=lambda s: s["t_start"],
    )
    out = []
    for k, g in enumerate(grips):
        if (g["goal"].get("params") or {}).get("state") != "closed":
            continue
        opens = [
            o["t_start"]
            for o in grips[k + 1 :]
            if (o["goal"].get("params") or {}).get("state") == "open"
        ]
        part = _held_part(doc, f"{hand[0]}_arm", g["t_start"])
        out.append((g["t_start"], min(opens, default=float("inf")), part))
    return out


def carried_moves(doc: dict[str, Any]) -> list[tuple[float, float, float]]:
    """(grip, first move's start, last move's end) of each two-handed grip: the moves made
    while both hands hold the part, and what happens between them (a walk carrying it)."""
    both = [
        (max(r0, l0), min(r1, l1))
        for r0, r1, r_part in _closed_spans(doc, "r_hand")
        for l0, l1, l_part in _closed_spans(doc, "l_hand")
        if min(r1, l1) > max(r0, l0) and r_part and r_part == l_part
    ]
    moves: dict[tuple[float, float], list[float]] = {}
    for s in doc["segments"]:
        params = (s.get("goal") or {}).get("params") or {}
        if s["kind"] not in ("TA", "TO") or s["track"] != "r_arm" or not params.get("two_handed"):
            continue
        for start, end in both:
            if start - EPS <= s["t_start"] < end:
                span = moves.setdefault((start, end), [])
                span.append(s["t_start"])
                span.append(s["t_end"])
    out = []
    for (start, _), times in moves.items():
        # consecutive segments of one move share ends: each move is a run of touching windows
        times.sort()
        out.append((start, min(times), max(times)))
    return out


def measure(doc: dict[str, Any]) -> list[tuple[float, float]]:
    """Per carried move: max |d(t) - d(grip)| (mm), and the largest change of one joint
    between two output frames inside it (deg)."""
    body = Body.of(doc)
    d = np.linalg.norm(body.points["r_hand"] - body.points["l_hand"], axis=1)
    q = np.asarray(doc["frames"]["q"], float)
    out = []
    for grip, start, end in carried_moves(doc):
        k0 = body.frame_at(grip)
        inside = np.flatnonzero((body.time >= start - EPS) & (body.time <= end + EPS))
        if inside.size:
            steps = np.abs(np.diff(q[inside[0] : inside[-1] + 1], axis=0))
            step = float(np.degrees(steps.max(initial=0.0)))
            out.append((float(np.abs(d[inside] - d[k0]).max()) * 1000.0, step))
    return out


def folder(path: Path) -> dict[str, list[tuple[float, float]]]:
    rows = {}
    for ir in sorted(path.glob("*/*.ir.json")):
        doc = json.loads(ir.read_text(encoding="utf-8"))
        rows[ir.parent.name] = measure(doc)
    return rows


def main(argv: list[str]) -> int:
    sets = [folder(Path(a)) for a in argv]
    names = sorted({n for s in sets for n, v in s.items() if v})
    for n in names:
        cells = ["  ".join(f"{v:7.1f} {w:5.1f}" for v, w in s.get(n, [])) or "-" for s in sets]
        print(f"{n:40s} " + "  |  ".join(cells))
    for k, s in enumerate(sets):
        values = [v for vs in s.values() for v, _ in vs]
        steps = [w for vs in s.values() for _, w in vs]
        over = sum(v > 5.0 for v in values)
        worst = max(values, default=0.0)
        print(
            f"set {k}: {len(values)} grips with carried moves, worst {worst:.1f} mm, "
            f"median {np.median(values) if values else 0.0:.1f} mm, over 5 mm: {over}; "
            f"joint step inside: worst {max(steps, default=0.0):.1f} deg, "
            f"over 12 deg: {sum(w > 12.0 for w in steps)}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
