"""A contact starts where its own approach ended, also when the other hand's contact starts first.

tests/data/contact/parallel_press.mtask: a parallel block, the left hand pressing a roof cover
while the right reaches a switch. The two contacts overlap in time, so the contact pass solves
them as one group from the body at the group's start, the right hand's. The left hand was then
still on its approach, and the state gives a dof its latest keyframe: the approach's first. The
left contact started from the hip (female P5: 1.22 m from the cover, against 0.09 m where its
approach ended) and the press only came up in its second phase.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

DATA = Path(__file__).resolve().parents[1] / "data" / "contact"


@pytest.mark.parametrize("manikin", [("female", 5), ("male", 95)])
def test_each_contact_starts_where_its_approach_ended(manikin: tuple[str, int]) -> None:
    ir, _ = compile_on(DATA / "parallel_press.mtask", manikin, until="contact")
    approaches = {(s.track, s.provenance.origin, s.end): s for s in ir.segments if s.kind == "TA"}
    checked = 0
    for to in (s for s in ir.segments if s.kind == "TO"):
        ta = approaches.get((to.track, to.provenance.origin, to.start))
        if ta is None or ta.keyframes is None or to.keyframes is None:
            continue
        shared = [n for n in to.keyframes.dofs if n in ta.keyframes.dofs and "_" in n]
        arm = [n for n in shared if n.startswith(to.track[0] + "_")]
        assert arm, (to.track, to.keyframes.dofs)
        end = {n: ta.keyframes.q[-1, ta.keyframes.dofs.index(n)] for n in arm}
        start = {n: to.keyframes.q[0, to.keyframes.dofs.index(n)] for n in arm}
        jump = max(abs(end[n] - start[n]) for n in arm)
        assert np.degrees(jump) < 0.01, (to.track, to.start, end, start)
        checked += 1
    assert checked == 2  # the left press and the right reach
