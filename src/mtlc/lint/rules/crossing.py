"""MT0612: the two hands work crossed over, each on the other's side of the body.

A procedure that gives the left hand a site on the manikin's right while the right hand works
on its left makes the arms cross: the forearms pass each other on the way and each hand works
reaching across the body. It is rarely meant; more often the sites were named from another
point of view (a rack's "left latch" as seen from behind it) or the coordinates written for a
manikin facing the other way. The examples' avionics rack had its latches so, and the hands
passed through each other on the way to the unit's handle (issue 19).

Wherever both hands are on their sites at once (a TO of each arm, the same time), the two sites
are seen in the pelvis's frame at the later of the two arrivals (the manikin faces +Z, its left
is +X); where the left hand's site lies more than ``CROSS_MARGIN`` to the right of the right
hand's, the pair of task lines is reported once, at the left hand's line. A part held in both
hands (one two-handed goal) is gripped across the body by construction and is not a crossing.
"""

from __future__ import annotations

import numpy as np

from mtlc.body.kinematics import quat_to_matrix
from mtlc.ir.model import Segment, SourceRef
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView, segment_finding

CROSS_MARGIN = 0.05  # m: sites this close across the midline are side by side, not crossed
EPS = 1e-9


def _on_sites(view: MotionView, side: str) -> list[Segment]:
    return [
        s for s in view.ir.on_track(f"{side}_arm") if s.kind == "TO" and s.goal.position is not None
    ]


def crossed_arms(view: MotionView) -> list[Finding]:
    """MT0612, once per pair of task lines, at the left hand's."""
    frames = view.ir.frames
    assert frames is not None
    out: list[Finding] = []
    seen: set[tuple[SourceRef, SourceRef]] = set()
    rights = _on_sites(view, "r")
    for left in _on_sites(view, "l"):
        for right in rights:
            if min(left.end, right.end) < max(left.start, right.start) - EPS:
                continue  # not on their sites at the same time
            if left.goal.params.get("two_handed") and left.goal.site == right.goal.site:
                continue  # one part in both hands
            key = (left.provenance.origin, right.provenance.origin)
            if key in seen:
                continue
            at = max(left.start, right.start)
            i = min(int(np.searchsorted(view.time, at - EPS)), len(view.time) - 1)
            turn = quat_to_matrix(frames.root_rotation[i])
            root = frames.root_position[i]
            x_left = float((turn.T @ (np.asarray(left.goal.position) - root))[0])
            x_right = float((turn.T @ (np.asarray(right.goal.position) - root))[0])
            if x_left >= x_right - CROSS_MARGIN:
                continue
            seen.add(key)
            msg = (
                f"the left hand works at `{left.goal.site}` {100 * (x_right - x_left):.0f} cm to "
                f"the right of the right hand at `{right.goal.site}` (at {view.time[i]:.2f} s): "
                "the arms cross"
            )
            help = (
                "give each hand the site on its own side (the manikin faces +Z; its left is +X), "
                "or turn the body to the work (`walk to SITE facing SITE`)"
            )
            out.append(segment_finding(view, "MT0612", left, msg, help))
    return out
