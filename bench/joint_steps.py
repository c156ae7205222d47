"""Which dof makes a compile's largest one-frame steps, when, and in which segment (issue 19).

    python bench/joint_steps.py KEEP_DIR [--over 12] [--all]

KEEP_DIR is a ``bench/motion.py --keep`` folder (one sub-folder per compile with its IR JSON).
Per output it prints the worst dof (as bench/human.py judges it: wrist and forearm pronation
inside a ``turn_fastener`` are left out), its step in degrees, the frame time and the segments
live at that step (kind, the last part of the path, and "start"/"end" when a segment begins or
ends between the two frames). Then it counts, over every output, the causes of the steps over
``--over`` degrees: the worst step per output, and with ``--all`` every such step. A cause is
the dof's group and the segment that sets that dof at the step (its own track first: a head
dof's gaze, an arm dof's reach or turn, else a whole-body segment), with the boundary it sits
on. Like bench/human.py it reads the IR JSON only and uses no mtlc code.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path
from typing import Any

import human
import numpy as np

GROUPS = (
    ("wrists", ("wrist_", "elbow_pro")),
    ("neck/head", ("neck_", "head_")),
    ("trunk", ("lumbar_", "thorax_")),
    ("shoulders/arms", ("clavicle_", "shoulder_", "elbow_flex")),
    ("legs", ("hip_", "knee_", "ankle_", "toes_")),
    ("root", ("root_",)),
)


def group(dof: str) -> str:
    for name, parts in GROUPS:
        if any(p in dof for p in parts):
            return name
    return "other"


def track_of(dof: str) -> tuple[str, ...]:
    """The tracks whose segments set this dof, its own first."""
    if dof.startswith(("neck_", "head_")):
        return ("head", "root")
    for side in ("r", "l"):
        if dof.startswith(f"{side}_") and group(dof) in ("wrists", "shoulders/arms"):
            return (f"{side}_hand", f"{side}_arm", "arms", "root")
    return ("root",)


def live(segments: list[dict[str, Any]], t0: float, t1: float) -> list[dict[str, Any]]:
    """Segments that overlap the step from t0 to t1, each with where the step lies in it."""
    out = []
    for s in segments:
        a, b = float(s["t_start"]), float(s["t_end"])
        if b < t0 - 1e-9 or a > t1 + 1e-9:
            continue
        where = "start" if t0 - 1e-9 <= a <= t1 + 1e-9 and a > 1e-9 else ""
        if t0 - 1e-9 <= b <= t1 + 1e-9:
            where = (where + "+end") if where else "end"
        what = str(s.get("path", "")).split(" > ")[-1]
        params = (s.get("goal") or {}).get("params") or {}
        if s["kind"] == "posture" and params.get("posture"):
            what = f"{what}:{params['posture']}"
        out.append({"track": s["track"], "kind": s["kind"], "what": what, "where": where})
    return out


def label(dof: str, segs: list[dict[str, Any]]) -> str:
    for tr in track_of(dof):
        mine = [s for s in segs if s["track"] == tr or (tr == "arms" and "arm" in s["track"])]
        if mine:
            s = next((m for m in mine if m["where"]), mine[0])
            return f"{s['kind']} {s['what']} {s['where'] or 'inside'}"
    return "none"


def steps_of(doc: dict[str, Any]) -> tuple[np.ndarray, list[str], np.ndarray]:
    """(T-1, D) strict steps in degrees (fastener-turn wrist steps zeroed), dof names, time."""
    f = doc["frames"]
    time = np.asarray(f["time"], float)
    T = len(time)
    names = list(f["dof_names"])
    q = np.asarray(f["q"], float).reshape(T, -1)
    steps = np.degrees(np.abs(np.diff(q, axis=0)))
    turns = [
        (s["t_start"], s["t_end"])
        for s in doc["segments"]
        if str(s.get("path", "")).endswith("turn_fastener")
    ]
    in_turn = human._in_windows(time, turns)
    step_in_turn = in_turn[:-1] | in_turn[1:]
    cols = np.array([any(n.endswith(d) for d in human.TURN_DOFS) for n in names])
    steps[step_in_turn[:, None] & cols[None, :]] = 0.0
    return steps, names, time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("keep", type=Path)
    ap.add_argument("--over", type=float, default=12.0)
    ap.add_argument("--all", action="store_true", help="count every step over, not the worst")
    args = ap.parse_args(argv)
    worst_causes: Counter[str] = Counter()
    all_causes: Counter[str] = Counter()
    outputs_of: dict[str, set[str]] = {}
    by_group: dict[str, list[float]] = {g: [] for g, _ in GROUPS}
    n_over = 0
    for sub in sorted(p for p in args.keep.iterdir() if p.is_dir()):
        for path in sorted(sub.glob("*.ir.json")):
            doc = json.loads(path.read_text(encoding="utf-8"))
            steps, names, time = steps_of(doc)
            if steps.size == 0:
                continue
            for g, _ in GROUPS:
                cols = [j for j, n in enumerate(names) if group(n) == g]
                if cols:
                    by_group[g].append(float(steps[:, cols].max()))
            k, d = np.unravel_index(int(np.argmax(steps)), steps.shape)
            segs = live(doc["segments"], float(time[k]), float(time[k + 1]))
            cause = f"{group(names[d])}: {label(names[d], segs)}"
            over = steps[k, d] > args.over
            n_over += over
            if over:
                worst_causes[cause] += 1
            where = "; ".join(
                f"{s['track']} {s['kind']} {s['what']}{' ' + s['where'] if s['where'] else ''}"
                for s in segs
            )
            print(
                f"{sub.name:<42} {names[d]:<16} {steps[k, d]:6.1f} deg @{time[k]:6.2f}s "
                f"(frame {k})  [{where}]"
            )
            if args.all:
                for kk, dd in zip(*np.nonzero(steps > args.over), strict=True):
                    s2 = live(doc["segments"], float(time[kk]), float(time[kk + 1]))
                    c = f"{group(names[dd])}: {label(names[dd], s2)}"
                    all_causes[c] += 1
                    outputs_of.setdefault(c, set()).add(sub.name)
    print(f"\noutputs over {args.over:g} deg: {n_over}")
    print("\nworst step per output, by cause (outputs over):")
    for c, n in worst_causes.most_common():
        print(f"  {n:4d}  {c}")
    if args.all:
        print("\nevery step over, by cause (steps, outputs):")
        for c, n in all_causes.most_common():
            print(f"  {n:5d} {len(outputs_of[c]):4d}  {c}")
    print("\nworst step per output by dof group: median p95 max (deg)")
    for g, vals in by_group.items():
        if vals:
            a = np.asarray(vals)
            print(
                f"  {g:<16} {np.median(a):6.1f} {np.percentile(a, 95):6.1f} {a.max():6.1f}"
                f"  over: {int(np.sum(a > args.over))} of {len(a)}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
