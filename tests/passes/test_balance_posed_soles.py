"""``balance._restore_contacts`` checks the feet's sole points of both feet in one forward
kinematics of the legs, or on the whole body's pose a ``restore_contacts_posed`` caller takes:
the same numbers, to the bit, as each foot's own ``part_site_positions`` (any rows, any
batch, with or without the dofs' axes), and so the same contact errors."""

from __future__ import annotations

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, part_site_positions, site_positions
from mtlc.metrics import FOOT_POINT_NAMES

SKELS = [build_manikin("gb10000_1988", "female", 5), build_manikin("gb10000_1988", "male", 95)]
BOTH = [f"{s}_{p}" for s in "rl" for p in FOOT_POINT_NAMES]


def bits(a: np.ndarray) -> list[int]:
    return np.ascontiguousarray(a).view(np.int64).ravel().tolist()


@pytest.mark.parametrize("skel", SKELS, ids=["female-p5", "male-p95"])
@pytest.mark.parametrize("n", [1, 2, 9, 48, 49, 257, 700])
def test_sole_points_of_both_feet_and_of_the_whole_pose_are_each_feet(skel, n) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(n)
    q = np.clip(skel.q_comfort + rng.normal(0, 0.4, (n, skel.n_dofs)), skel.lower, skel.upper)
    root = rng.normal(0, 1, (n, 3))
    yaw = rng.uniform(-3, 3, n)
    rot = np.stack([np.cos(yaw / 2), 0 * yaw, np.sin(yaw / 2), 0 * yaw], 1)
    for with_axes in (False, True):
        whole = forward(skel, q, root, rot, with_axes=with_axes)
        for m in sorted({1, max(n // 3, 1), n}):
            rows = np.sort(rng.choice(n, m, replace=False))
            each = np.concatenate(
                [
                    part_site_positions(
                        skel, q[rows], root[rows], rot[rows], [f"{s}_{p}" for p in FOOT_POINT_NAMES]
                    )
                    for s in "rl"
                ],
                axis=1,
            )
            both = part_site_positions(skel, q[rows], root[rows], rot[rows], BOTH)
            posed = site_positions(skel, whole if m == n else whole.rows(rows), BOTH)
            assert bits(both) == bits(each)
            assert bits(posed) == bits(each)
