"""Trunk lean (lumbar + thorax flexion, degrees) from IR JSON files (issue 19, the upright pass).

Per output: the largest flexion during a look with nothing else going on (a gaze segment, no
reach, posture or walk and no arm segment covering the frame), the largest over the free time
more than 1 s after any such segment ended (the way up has had its time), the mean over the
free time, and the free seconds. Reads only the IR files: no mtlc code.

    python bench/trunk_lean.py KEEPDIR_OR_FILES...   (e.g. bench/motion.py's --keep folder)
"""

from __future__ import annotations

import glob
import json
import os
import sys

import numpy as np

BUSY_KINDS = ("TA", "TO", "posture", "locomotion")
SETTLE = 1.0  # s after a busy segment before "free_max" counts a frame


def lean_of(path: str) -> tuple[float, float, float, float]:
    """(inspection max, free max after SETTLE, free mean, free seconds) of one IR file."""
    with open(path, encoding="utf-8") as f:
        ir = json.load(f)
    frames = ir["frames"]
    t = np.asarray(frames["time"])
    q = np.asarray(frames["q"])
    names = frames["dof_names"]
    flexion = np.degrees(q[:, names.index("lumbar_flex")] + q[:, names.index("thorax_flex")])
    busy = np.zeros(len(t), dtype=bool)
    settling = np.zeros(len(t), dtype=bool)
    gaze = np.zeros(len(t), dtype=bool)
    for seg in ir["segments"]:
        inside = (t >= seg["t_start"] - 1e-6) & (t <= seg["t_end"] + 1e-6)
        if seg["kind"] == "gaze":
            gaze |= inside
        elif seg["kind"] in BUSY_KINDS or seg["track"].endswith("_arm"):
            busy |= inside
            settling |= (t >= seg["t_start"] - 1e-6) & (t <= seg["t_end"] + SETTLE)
    free = ~busy

    def largest(mask: np.ndarray) -> float:
        return float(np.abs(flexion[mask]).max()) if mask.any() else 0.0

    mean = float(np.abs(flexion[free]).mean()) if free.any() else 0.0
    return largest(gaze & free), largest(~settling), mean, float(free.sum() / frames["fps"])


def main(args: list[str]) -> None:
    files: list[str] = []
    for arg in args:
        pattern = os.path.join(arg, "**", "*.ir.json")
        files += sorted(glob.glob(pattern, recursive=True)) if os.path.isdir(arg) else [arg]
    total = np.zeros(3)
    for path in files:
        row = lean_of(path)
        total += row[:3]
        print(
            f"{os.path.relpath(path)[-70:]:70s} insp_max {row[0]:6.1f}  free_max(>1s) "
            f"{row[1]:6.1f}  free_mean {row[2]:5.1f}  free_s {row[3]:5.1f}"
        )
    if len(files) > 1:
        print(
            f"SUM over {len(files)}: insp_max {total[0]:.1f} free_max {total[1]:.1f} "
            f"free_mean {total[2]:.1f}"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
