"""Smoothing keeps a standing leg's angles where the blend left the root put (docs/passes.md,
"smoothing"): the foot stays exactly where the gait planted it, no IK re-pin needed."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.body import forward
from mtlc.body.kinematics import forward_rows_changed
from mtlc.diagnostics import DiagnosticSink
from mtlc.metrics import contact_mask, foot_points, foot_stance
from mtlc.passes import smooth
from mtlc.passes.context import PassContext

WALK = """use stdlib.actions

scene yard {{
    site far at ({x}, 0, {z}) cm
}}

task walk {{
    scene yard
    walk_to(far)
}}
"""


@pytest.mark.parametrize(("spec", "x", "z"), [(("female", 5), 0, 600), (("male", 95), 350, 420)])
def test_standing_legs_keep_their_angles_through_the_blend(
    tmp_path: Path, spec: tuple[str, int], x: int, z: int
) -> None:
    path = tmp_path / "walk.mtask"
    path.write_text(WALK.format(x=x, z=z), encoding="utf-8")
    ir, _ = compile_on(path, spec, until="balance")
    before = copy.deepcopy(ir.frames)
    smooth.run(ir, PassContext(DiagnosticSink()))
    f, skel = ir.frames, ir.skeleton
    blended = np.flatnonzero(np.abs(f.q - before.q).max(axis=1) > 0.0)
    assert blended.size > 100  # the lift-offs were blended: the test has something to check
    still = (f.root_position == before.root_position).all(axis=1)
    pose0 = forward(skel, before.q, before.root_position, before.root_rotation, with_axes=False)
    pose1 = forward(skel, f.q, f.root_position, f.root_rotation, with_axes=False)
    soles0, soles1 = foot_points(skel, pose0), foot_points(skel, pose1)
    touching = contact_mask(soles0, foot_stance(ir, f.time), ir.ground)
    touching = touching.reshape(len(f.time), 2, -1).any(axis=2)
    kept = 0
    for k, side in enumerate("rl"):
        legs = skel.dofs_of_joints([f"{side}_hip", f"{side}_knee", f"{side}_ankle", f"{side}_toes"])
        rows = blended[still[blended] & touching[blended, k]]
        kept += rows.size
        assert np.array_equal(f.q[np.ix_(rows, legs)], before.q[np.ix_(rows, legs)])
        feet = slice(4 * k, 4 * k + 4)
        assert np.abs(soles1[rows, feet] - soles0[rows, feet]).max(initial=0.0) <= 1e-12
    assert kept > 50


def test_frames_after_the_blend_posed_from_before_as_forward(tmp_path: Path) -> None:
    """``forward_rows_changed`` (smooth's pose after the blend) gives ``forward``'s numbers, bit for bit, on frames the blend
    left alone, frames it changed below a joint with the root put, and frames it moved whole."""
    path = tmp_path / "walk.mtask"
    path.write_text(WALK.format(x=350, z=420), encoding="utf-8")
    ir, _ = compile_on(path, ("male", 95), until="balance")
    f, skel = ir.frames, ir.skeleton
    q0, root0, rot = f.q.copy(), f.root_position.copy(), f.root_rotation
    smooth.smooth_frames(f, smooth.boundaries(ir), skel.lower, skel.upper)
    q, root = f.q.copy(), f.root_position.copy()
    rows = np.flatnonzero((q != q0).any(axis=1))
    assert rows.size > 100
    q[rows[::3]] = q0[rows[::3]]  # left alone
    root[rows[::3]] = root0[rows[::3]]
    root[rows[1::3]] = root0[rows[1::3]]  # the root put: a leg, the trunk... posed again
    root[rows[2::3], 1] += 1e-3  # the root moved: posed whole
    before = forward(skel, q0, root0, rot, with_axes=False)
    got = forward_rows_changed(skel, before, q0, root0, q, root, rot)
    want = forward(skel, q, root, rot, with_axes=False)
    assert np.array_equal(got.R.view(np.int64), want.R.view(np.int64))
    assert np.array_equal(got.p.view(np.int64), want.p.view(np.int64))
