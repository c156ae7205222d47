"""Where a part carried in both hands is while walking (issue 19; docs/passes.md, carry_pose).

    PYTHONPATH=src python bench/carried_load.py FILE.mtask [FILE ...]

Each procedure is compiled in process for the 14 GB 10000-88 manikins; for each walk during
which both hands hold one two-handed part (``mtlc.passes.carry.carries``), on the output
frames: the hands' mid-point's horizontal distance from the lumbar joint and its height above
the floor, in the middle of the walk and the largest over it. A manikin with no carried walk
(its hands fell short of the part) prints nothing after its name.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.lint.manikins import all_manikins
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.carry import carries
from mtlc.semantics import schedule


def main(paths: list[str]) -> int:
    for path in paths:
        for m in all_manikins():
            (timeline,) = run_frontend([Path(path)]).timelines
            timeline = schedule.for_manikin(timeline, m)
            ir = run_motion(timeline, DiagnosticSink(), MotionOptions())
            fr, skel = ir.frames, ir.skeleton
            assert fr is not None
            spans = carries(ir)
            out = []
            for seg in ir.on_track("root"):
                held = any(c.start <= seg.start + 1e-9 and c.end >= seg.end - 1e-9 for c in spans)
                if seg.kind != "locomotion" or not held:
                    continue
                rows = np.flatnonzero((fr.time >= seg.start) & (fr.time <= seg.end))
                pose = forward(skel, fr.q[rows], fr.root_position[rows], fr.root_rotation[rows])
                hands = np.asarray(site_positions(skel, pose, ["r_hand", "l_hand"])).mean(axis=1)
                lumbar = pose.p[:, skel.joint_index("lumbar")]
                ahead = np.hypot(hands[:, 0] - lumbar[:, 0], hands[:, 2] - lumbar[:, 2]) * 100
                height = (hands[:, 1] - ir.ground) * 100
                mid = rows.size // 2
                out.append(
                    f"walk {seg.start:.1f}-{seg.end:.1f} s: from the lumbar joint {ahead[mid]:.0f} cm "
                    f"(max {ahead.max():.0f}), height {height[mid]:.0f} cm (max {height.max():.0f})"
                )
            print(f"{Path(path).stem} {m.sex}-p{m.percentile}", "; ".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
