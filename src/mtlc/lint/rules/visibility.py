"""MT0607: a site being reached or worked on (a TA or TO segment) lies outside the view cone.

Per frame of each reach, the angle between the head's forward axis and the line from the eye to
the reached site (mtlc.ergonomics.view); reported once per task line, at its worst frame.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mtlc.body.kinematics import Pose
from mtlc.diagnostics import Span
from mtlc.ergonomics.view import outside_cone, site_view_angles
from mtlc.ir.model import Segment, SourceRef
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView

REACH_KINDS = ("TA", "TO")


def frame_window(time: np.ndarray, start: float, end: float) -> slice:
    """The frames from ``start`` to ``end`` inclusive."""
    lo = int(np.searchsorted(time, start - 1e-9, side="left"))
    hi = int(np.searchsorted(time, end + 1e-9, side="right"))
    return slice(lo, hi)


def pose_frames(pose: Pose, frames: slice | np.ndarray) -> Pose:
    """The poses of some frames only (a slice or an index array)."""
    return replace(pose, R=pose.R[frames], p=pose.p[frames], axes=pose.axes[frames],
                   root=pose.root[frames])  # fmt: skip


def site_out_of_view(view: MotionView) -> list[Finding]:
    half = view.config.view_cone_half_angle
    worst: dict[SourceRef, tuple[float, int, Segment]] = {}  # task line -> angle, frame, reach
    for seg in view.ir.segments:
        if seg.kind not in REACH_KINDS or seg.goal.position is None:
            continue
        frames = frame_window(view.time, seg.start, seg.end)
        if frames.stop <= frames.start:
            continue
        target = np.asarray(seg.goal.position, dtype=float)
        angle = site_view_angles(view.ir.skeleton, pose_frames(view.pose, frames), target)
        bad = outside_cone(angle, half)
        if not bad.any():
            continue
        k = int(np.argmax(np.where(bad, angle, -np.inf)))
        key = seg.provenance.origin
        if key not in worst or angle[k] > worst[key][0]:
            worst[key] = (float(angle[k]), frames.start + k, seg)
    ordered = sorted(worst.values(), key=lambda w: w[1])
    return [_finding(view, half, angle, frame, seg) for angle, frame, seg in ordered]


def _finding(view: MotionView, half: float, angle: float, frame: int, seg: Segment) -> Finding:
    o = seg.provenance.origin
    msg = (
        f"site `{seg.goal.site}` is outside the {half:g}° view cone while it is reached or worked "
        f"on: {math.degrees(angle):.1f}° off the line of sight at {view.time[frame]:.2f} s in "
        f"`{' > '.join(seg.provenance.path)}`"
    )
    return Finding(
        "MT0607",
        msg,
        Span(o.file, o.line, o.column, o.end_line, o.end_column),
        help="look at the site first (`look`), turn the body toward it, or move the site into view",
        manikins=(view.manikin,),
        details=(msg,),
    )
