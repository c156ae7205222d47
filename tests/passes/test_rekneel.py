"""A kneel while the body already kneels: a hold on the same knees, the two-knee kneel's last
phases on to (or back from) both knees, never a new stepping kneel from standing (docs/passes.md,
"A kneel while kneeling")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR, Segment
from mtlc.passes import run_motion
from mtlc.passes.posture import KNEE_HEIGHT

DATA = Path(__file__).resolve().parents[1] / "data" / "kneel"
MM = 1e-3


def postures(name: str) -> tuple[MotionIR, list[Segment]]:
    prog = run_frontend([DATA / name])
    assert prog.timelines, [d.message for d in prog.diagnostics]
    ir = run_motion(prog.timelines[0], prog.sink, until="posture")
    kneels = sorted(
        (s for s in ir.on_track("root")
         if s.kind == "posture" and s.goal.params.get("posture") == "kneel"),
        key=lambda s: s.start,
    )  # fmt: skip
    return ir, kneels


def knee_heights(ir: MotionIR, seg: Segment) -> np.ndarray:
    """(N, 2) right and left knee centres above the ground on a kneel's keyframes."""
    kf = seg.keyframes
    assert kf is not None and kf.root_position is not None
    skel = ir.skeleton
    q = np.tile(skel.q_comfort, (len(kf.time), 1))
    q[:, [skel.dof_index(n) for n in kf.dofs]] = kf.q
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (len(q), 1))
    pose = forward(skel, q, kf.root_position, rot, with_axes=False)
    knees = [skel.joint_index("r_knee"), skel.joint_index("l_knee")]
    return np.asarray(pose.p[:, knees, 1]) - ir.ground


def test_a_kneel_on_the_same_knees_holds_the_kneel() -> None:
    """kneel(2), pick, kneel(2): the second keeps legs and root where the first left them (it
    stepped from standing before: the root rose 0.38 m to a standing height first)."""
    ir, kneels = postures("k04_kneel_twice.mtask")
    assert len(kneels) == 4
    first = kneels[0].keyframes
    assert first is not None and first.root_position is not None
    for seg in kneels[1:]:
        kf = seg.keyframes
        assert kf is not None and kf.root_position is not None
        assert seg.result["steps"] == [] and seg.result["rolls"] == []
        np.testing.assert_allclose(kf.root_position, first.root_position[[-1, -1]], atol=1e-9)
        held = [first.dofs.index(n) for n in kf.dofs]
        np.testing.assert_allclose(kf.q, np.tile(first.q[-1, held], (len(kf.q), 1)), atol=1e-9)
        assert "lumbar_flex" not in kf.dofs  # the trunk is the reaches'
        assert np.all(knee_heights(ir, seg) <= KNEE_HEIGHT + 2 * MM)


def test_one_knee_to_both_and_back_never_stands_up() -> None:
    """kneel(1), kneel(1), kneel(2), kneel(2), kneel(1): the right knee stays down throughout;
    the left one comes down in the third and up again in the fifth, the root never near a
    standing height."""
    ir, kneels = postures("k05_one_knee_both_and_back.mtask")
    assert [s.goal.params["knees"] for s in kneels] == [1, 1, 2, 2, 1]
    stand_y = float(kneels[0].keyframes.root_position[0, 1]) - ir.ground
    kneel_y = float(kneels[0].keyframes.root_position[-1, 1]) - ir.ground
    for seg in kneels[1:]:
        kf = seg.keyframes
        assert kf is not None and kf.root_position is not None
        heights = knee_heights(ir, seg)
        assert np.all(heights[:, 0] <= KNEE_HEIGHT + 5 * MM)  # the right knee stays down
        assert float(kf.root_position[:, 1].max()) - ir.ground < kneel_y + 0.1 < stand_y
    both, up = kneels[2], kneels[4]
    assert knee_heights(ir, both)[-1, 1] == pytest.approx(KNEE_HEIGHT, abs=5 * MM)
    assert [s["foot"] for s in both.result["steps"]] == ["l"]
    assert knee_heights(ir, up)[0, 1] == pytest.approx(KNEE_HEIGHT, abs=5 * MM)
    assert knee_heights(ir, up)[-1, 1] > 0.3  # the left foot stands in front again
    assert [s["foot"] for s in up.result["steps"]] == ["l"]


def test_the_tucked_foot_is_found_once_per_manikin_and_side() -> None:
    """Every kneel asks for the tucked foot of its manikin (two nested bisections): it is
    kept on the skeleton, the same numbers as finding it again, and a caller's change to the
    heel it got does not reach the next caller."""
    from mtlc.body import build_manikin
    from mtlc.passes.kneel import _tucked_foot, tucked_foot

    skel = build_manikin("gb10000_1988", "female", 5)
    reach, heel = tucked_foot(skel)
    again = _tucked_foot(skel, "r")
    assert reach == again[0] and np.array_equal(heel, again[1])
    heel[:] = 9.0
    assert np.array_equal(tucked_foot(skel)[1], again[1])
    assert tucked_foot(skel, "l")[0] == pytest.approx(reach, abs=1e-9)  # a symmetric manikin


@pytest.mark.parametrize("spec", [("female", 5), ("male", 95)])
@pytest.mark.parametrize("side", ["r", "l"])
def test_the_toe_height_by_rodrigues_is_the_legs_forward_kinematics(spec, side) -> None:
    """``toe_above_balls`` (the ankle placed once, the toe turned by Rodrigues) gives the
    numbers ``part_site_positions`` of the whole leg gives, over knee and toe angles."""
    from mtlc.body import build_manikin, part_site_positions
    from mtlc.passes.kneel import toe_above_balls

    skel = build_manikin("gb10000_1988", *spec)
    names = [f"{side}_{n}" for n in ("ball_med", "ball_lat", "toe")]
    k_dof, t_dof = skel.dof_index(f"{side}_knee_flex"), skel.dof_index(f"{side}_toes_dorsi")
    rng = np.random.default_rng(3)
    for _ in range(12):
        q = np.asarray(skel.q_comfort, dtype=float).copy()
        q[k_dof] = rng.uniform(0.0, float(skel.upper[k_dof]))
        q[skel.dof_index(f"{side}_ankle_dorsi")] = rng.uniform(-0.5, 0.3)
        height = toe_above_balls(skel, q, side)
        for t in rng.uniform(0.0, float(skel.upper[t_dof]), 5):
            q[t_dof] = t
            pts = part_site_positions(skel, q[None], None, None, names)[0]
            assert height(float(t)) == pytest.approx(pts[2, 1] - pts[:2, 1].mean(), abs=1e-12)
