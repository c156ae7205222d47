"""Rules over one manikin's compiled frames: MT0603 joint limits, MT0604 ground penetration,
MT0605 RULA. Each reports once per task line, at the worst frame of that line.

MT0603 and MT0604 read what the verify pass measured (``MotionIR.verification``: the limit
excess of every dof and the depth of every body point below the floor, per frame) and apply
the lint configuration's thresholds (``limit-deg``, ``penetration-mm``) to it; lint then gives
these findings instead of compile's MT0513 and MT0512 (docs/lint.md)."""

from __future__ import annotations

import math

import numpy as np

from mtlc.ir.model import Verification
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView
from mtlc.metrics import foot_stance


def _finding(view: MotionView, code: str, message: str, frame: int, help: str) -> Finding:
    return Finding(
        code,
        message,
        view.span(frame),
        help=help,
        manikins=(view.manikin,),
        details=(message,),
    )


def _verified(view: MotionView) -> Verification:
    v = view.ir.verification
    if v is None:  # the motion passes always end with verify
        raise ValueError("the motion is not verified: run the verify pass last")
    return v


def joint_limits(view: MotionView) -> list[Finding]:
    skel = view.ir.skeleton
    tol = math.radians(view.config.limit_deg)
    signed = _verified(view).limit_excess  # (N, D): + past the upper limit, - the lower
    above, below = np.maximum(signed, 0.0), np.maximum(-signed, 0.0)
    out = []
    for d in np.flatnonzero(((above > tol) | (below > tol)).any(axis=0)):
        excess = np.maximum(above[:, d], below[:, d])
        for i in view.worst_per_line(excess > tol, excess):
            side = "upper" if above[i, d] >= below[i, d] else "lower"
            msg = (
                f"joint `{skel.dof_names[d]}` goes past its {side} limit in `{view.where(i)}`: "
                f"{math.degrees(excess[i]):.1f}° at {view.time[i]:.2f} s"
            )
            out.append(
                _finding(
                    view,
                    "MT0603",
                    msg,
                    i,
                    "give the goal a posture that keeps the joint in range, or move the site",
                )
            )
    return out


def ground_penetration(view: MotionView) -> list[Finding]:
    depth = _verified(view).penetration_frames
    bad = depth > view.config.penetration_mm / 1000.0
    out = []
    for i in view.worst_per_line(bad, depth):
        msg = (
            f"the body goes below the ground in `{view.where(i)}`: "
            f"{depth[i] * 1000:.0f} mm at {view.time[i]:.2f} s"
        )
        out.append(
            _finding(
                view,
                "MT0604",
                msg,
                i,
                "raise the site or choose a posture that keeps "
                "the body above the floor (kneel rather than squat deeper)",
            )
        )
    return out


def rula(view: MotionView) -> list[Finding]:
    from mtlc.ergonomics import rula as R  # written alongside; imported when the rule runs

    both_feet = foot_stance(view.ir, view.time).all(axis=1)
    scores = R.task_scores(view.ir, view.pose, view.q, view.time, both_feet)
    grand = R.worst_grand(scores)
    threshold = view.config.rula_threshold
    out = []
    for i in view.worst_per_line(grand >= threshold, grand.astype(float)):
        side = max(scores, key=lambda s: int(scores[s].grand[i]))
        s = scores[side]
        msg = (
            f"RULA score {int(grand[i])} (threshold {threshold}) in `{view.where(i)}`: "
            f"at {view.time[i]:.2f} s, {'right' if side == 'r' else 'left'} side, upper arm "
            f"{int(s.upper_arm[i])}, wrist {int(s.wrist[i])}, neck {int(s.neck[i])}, trunk "
            f"{int(s.trunk[i])}"
        )
        out.append(
            _finding(
                view,
                "MT0605",
                msg,
                i,
                "bring the work nearer, between elbow and "
                "shoulder height, so the arm and trunk stay near neutral",
            )
        )
    return out
