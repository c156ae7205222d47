"""``output_pose``: the verify pass's pose of the output frames, handed to lint and metrics."""

from __future__ import annotations

import numpy as np

from mtlc.body import build_manikin, forward
from mtlc.body.kinematics import forget_output_pose, output_pose

SK = build_manikin("gb10000_1988", "female", 5)


def _frames(n: int = 80) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    q = rng.uniform(SK.lower, SK.upper, (n, SK.n_dofs))
    root = rng.normal(size=(n, 3))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return q, root, rot


def _same(a, b) -> bool:  # type: ignore[no-untyped-def]
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))


def test_a_kept_pose_is_handed_to_the_next_asker_of_the_same_frames() -> None:
    q, root, rot = _frames()
    kept = output_pose(SK, q, root, rot, keep=True)
    taken = output_pose(SK, q.copy(), root.copy(), rot.copy())
    assert taken is kept
    want = forward(SK, q, root, rot, with_axes=False)
    assert _same((taken.R, taken.p, taken.root), (want.R, want.p, want.root))
    # taking it forgot it: the next asker poses the frames again
    assert output_pose(SK, q, root, rot) is not kept


def test_frames_changed_after_the_pose_was_kept_are_posed_again() -> None:
    q, root, rot = _frames()
    kept = output_pose(SK, q, root, rot, keep=True)
    q[5, 3] += 1e-12  # in place: the kept pose no longer describes these frames
    fresh = output_pose(SK, q, root, rot)
    assert fresh is not kept
    want = forward(SK, q, root, rot, with_axes=False)
    assert _same((fresh.R, fresh.p), (want.R, want.p))
    assert not np.array_equal(fresh.R[5], kept.R[5])


def test_a_signed_zero_is_another_frame() -> None:
    q, root, rot = _frames()
    q[:, 0] = 0.0
    kept = output_pose(SK, q, root, rot, keep=True)
    q[:, 0] = -0.0
    assert output_pose(SK, q, root, rot) is not kept


def test_a_pose_nobody_took_is_forgotten() -> None:
    q, root, rot = _frames()
    kept = output_pose(SK, q, root, rot, keep=True)
    forget_output_pose()  # what a compile does first
    assert output_pose(SK, q, root, rot) is not kept
