"""``balance.tip_heights`` (the fingertip's height with the wrist turned, from one forward
kinematics of the frames and a rotation about the dof's axis) against whole-body forward
kinematics of each turned posture, for random postures, root poses, manikins and dofs: the
shortcut is exact, so a wrong axis, pivot or sign is off by centimetres."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward, site_positions
from mtlc.ir.model import Frames
from mtlc.passes import balance

MANIKINS = {
    (sex, pct): build_manikin("gb10000_1988", sex, pct)
    for sex in ("female", "male")
    for pct in (5, 95)
}


@settings(max_examples=30, deadline=None)
@given(
    who=st.sampled_from(sorted(MANIKINS)),
    side=st.sampled_from(("r", "l")),
    dof=st.sampled_from(("wrist_flex", "elbow_flex", "shoulder_flex")),
    seed=st.integers(0, 2**31 - 1),
)
def test_tip_heights_match_forward_kinematics_of_each_turned_posture(
    who: tuple[str, int], side: str, dof: str, seed: int
) -> None:
    skel = MANIKINS[who]
    rng = np.random.default_rng(seed)
    n, m = 5, 7
    q = rng.uniform(skel.lower, skel.upper, size=(n, skel.n_dofs))
    rot = rng.normal(size=(n, 4))
    rot /= np.linalg.norm(rot, axis=1, keepdims=True)
    frames = Frames(30.0, np.arange(n) / 30.0, rng.normal(0.0, 0.5, (n, 3)), rot, q)
    k = skel.dof_index(f"{side}_{dof}")
    change = rng.uniform(-1.5, 1.5, size=(n, m))
    tip = balance.TIP_SITES[side]
    rows = np.arange(n)

    fast = balance.tip_heights(skel, frames, rows, k, change, tip)

    turned = np.repeat(q, m, axis=0)
    turned[:, k] += change.ravel()
    pose = forward(
        skel, turned, np.repeat(frames.root_position, m, axis=0), np.repeat(rot, m, axis=0)
    )
    slow = site_positions(skel, pose, tip)[:, 1].reshape(n, m)
    np.testing.assert_allclose(fast, slow, atol=1e-12, rtol=0)
