"""Contact goals of a compiled motion, and manikins by stature, for lint and report.

Until issue 18 this module also screened the manikins between the extremes for reach (one
batched IK call from the nearest compiled manikin). The screen was not conservative (on the
fuel filter it reported MT0501 for 4 manikins the full compile shows reaching), so every
manikin is now compiled in full (mtlc.lint.engine, mtlc.executor) and only the look-ups the
sweep's readers share are left here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtlc.body.anthropometry import measure
from mtlc.ir.model import MotionIR, Segment
from mtlc.passes.approach import HAND_NAMES
from mtlc.passes.tool import is_stroke
from mtlc.semantics.timeline import ManikinSpec


def stature(spec: ManikinSpec) -> float:
    return measure(spec.population, spec.sex, spec.percentile, "stature")


@dataclass
class Reach:
    segment: Segment
    frame: int  # the output frame where the hand arrives


def contact_goals(ir: MotionIR) -> list[Reach]:
    """Each TO segment of the arms with a world target, once per (task line, site, arm)."""
    assert ir.frames is not None
    t = ir.frames.time
    seen: set[tuple[object, ...]] = set()
    out = []
    for seg in ir.segments:
        if seg.kind != "TO" or seg.goal.position is None or is_stroke(seg):
            continue
        if seg.goal.effector not in HAND_NAMES and "tool" not in seg.goal.params:
            continue  # a hand, or a tool's tip on its site (docs/tools.md)
        key = (seg.provenance.origin, seg.goal.site, seg.track)
        if key in seen:
            continue
        seen.add(key)
        out.append(Reach(seg, min(int(np.searchsorted(t, seg.end - 1e-9)), len(t) - 1)))
    return out
