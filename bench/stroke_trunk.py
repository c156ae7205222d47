"""How much the trunk (and neck) moves while a wrench's strokes turn one fastener (issue 19).

    python bench/stroke_trunk.py PATH [PATH ...] [--worst 10]

PATH is an IR JSON file or a folder searched for ``*.ir.json`` (a ``bench/motion.py --keep``
folder). A fastener's strokes are the run of consecutive stroke segments (a ``result`` with a
``swing``) on one track and site; over the frames from the first stroke's start to the last
one's end it takes the range (max - min, degrees) of every ``lumbar_*`` and ``thorax_*`` dof
and of every ``neck_*`` and ``head_*`` dof, and reports per run the largest of each. "inner"
leaves out the first and last stroke (they blend from and back to the reach pose). A mechanic
keeps the trunk still and swings the wrench with the arm. Reads the IR JSON only.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

TRUNK = ("lumbar_", "thorax_")
NECK = ("neck_", "head_")


def stroke_runs(segments: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    """Consecutive stroke segments on one track and site, in time order."""
    runs: dict[tuple[str, str], list[list[dict[str, Any]]]] = {}
    for s in sorted(segments, key=lambda s: float(s["t_start"])):
        if "swing" not in (s.get("result") or {}):
            continue
        key = (s["track"], s["goal"]["site"])
        group = runs.setdefault(key, [])
        if group and abs(float(group[-1][-1]["t_end"]) - float(s["t_start"])) <= 1e-6:
            group[-1].append(s)
        else:
            group.append([s])
    return [run for groups in runs.values() for run in groups]


def span_range(frames: dict[str, Any], t0: float, t1: float, parts: tuple[str, ...]) -> float:
    """Largest range (deg) over [t0, t1] of the dofs whose names hold one of ``parts``."""
    time = np.asarray(frames["time"], float)
    q = np.asarray(frames["q"], float)
    cols = [i for i, n in enumerate(frames["dof_names"]) if any(p in n for p in parts)]
    rows = (time >= t0 - 1e-6) & (time <= t1 + 1e-6)
    if not cols or rows.sum() < 2:
        return 0.0
    sub = q[np.ix_(rows, cols)]
    return math.degrees(float((sub.max(axis=0) - sub.min(axis=0)).max()))


def measure(path: Path) -> list[dict[str, Any]]:
    """One row per fastener's strokes in an IR JSON file."""
    d = json.loads(path.read_text())
    frames = d.get("frames")
    if not frames:
        return []
    out = []
    for run in stroke_runs(d["segments"]):
        t0, t1 = float(run[0]["t_start"]), float(run[-1]["t_end"])
        row = {
            "file": str(path),
            "site": run[0]["goal"]["site"],
            "strokes": len(run),
            "reach": sorted({(s["result"] or {}).get("reach", "?") for s in run}),
            "trunk": span_range(frames, t0, t1, TRUNK),
            "neck": span_range(frames, t0, t1, NECK),
        }
        if len(run) > 2:
            i0, i1 = float(run[1]["t_start"]), float(run[-2]["t_end"])
            row["trunk_inner"] = span_range(frames, i0, i1, TRUNK)
            row["neck_inner"] = span_range(frames, i0, i1, NECK)
        out.append(row)
    return out


def files(paths: list[str]) -> list[Path]:
    out: list[Path] = []
    for p in map(Path, paths):
        out.extend(sorted(p.rglob("*.ir.json")) if p.is_dir() else [p])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--worst", type=int, default=8)
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args()
    rows = [r for f in files(args.paths) for r in measure(f)]
    print(f"{len(rows)} fasteners' strokes")
    for key in ("trunk", "trunk_inner", "neck", "neck_inner"):
        v = np.array([r[key] for r in rows if key in r])
        if len(v):
            print(f"{key:12s} deg  median {np.median(v):6.2f}  p95 {np.percentile(v, 95):6.2f}  "
                  f"worst {v.max():6.2f}  over 3 deg {int((v > 3).sum())} of {len(v)}")  # fmt: skip
    for r in sorted(rows, key=lambda r: -r["trunk"])[: args.worst]:
        print(f"  trunk {r['trunk']:6.2f} neck {r['neck']:6.2f}  {r['site']:14s} "
              f"x{r['strokes']:<3d} {','.join(r['reach']):10s} {r['file']}")  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
