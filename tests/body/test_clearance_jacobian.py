"""The clearance solve's analytic Jacobian against finite differences, and what the solve leaves.

``keep_clear``'s Levenberg-Marquardt took its Jacobian by finite differences (one arm-only
forward kinematics per dof per iteration); ``_jacobian`` now computes it from the dofs' world
axes. These tests hold it to central differences of the residuals themselves on random
postures of random manikins, and hold the solve to its purpose: a free arm slightly inside the
trunk or a thigh comes out.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward
from mtlc.body.capsules import clearance, self_intersection, side_limbs
from mtlc.body.ik import clearance as ik
from mtlc.body.kinematics import dof_world_axes
from mtlc.lint.manikins import all_manikins
from mtlc.passes.verify import TOLERANCE

MANIKINS = all_manikins()
STEP = 1e-6  # rad, central differences: truncation ~1e-12, rounding ~1e-10 of a metre
KINK = 1e-4  # m: a depth this close to 0 is where the clipped residual bends; not compared


def _postures(seed: int, pick: int, side: str, n: int = 40) -> tuple:
    """Arm postures of one manikin standing: the arm's dofs anywhere in their limits (some
    inside the trunk or a thigh), and every other row the comfort arm swung in or out at the
    shoulder (-0.6 to 0.6 rad: a third of those inside), the rest of the body the comfort
    pose turned a little."""
    spec = MANIKINS[pick % len(MANIKINS)]
    sk = build_manikin(spec.population, spec.sex, spec.percentile)
    rng = np.random.default_rng(seed)
    dofs = ik.arm_dofs(sk, side)
    q = np.tile(sk.q_comfort, (n, 1)) + rng.normal(0.0, 0.05, (n, sk.n_dofs))
    q[::2, dofs] = rng.uniform(sk.lower[dofs], sk.upper[dofs], (len(q[::2]), len(dofs)))
    q[1::2, sk.dof_index(f"{side}_shoulder_abd")] = rng.uniform(-0.6, 0.6, len(q[1::2]))
    q = sk.clip(q)
    root = (np.tile([0.0, 0.9, 0.0], (n, 1)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)))
    return sk, rng, dofs, q, root


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    pick=st.integers(0, 13),
    side=st.sampled_from(["r", "l"]),
    clear_weight=st.sampled_from([1.0, 30.0]),
    seeded=st.booleans(),
)
def test_the_analytic_jacobian_is_the_residuals_derivative(
    seed: int, pick: int, side: str, clear_weight: float, seeded: bool
) -> None:
    """``_jacobian`` equals central differences of ``_res`` to 1e-6 (its entries are up to
    ~50: weight 30 times a lever of a metre or so) on every row, every dof, every residual but
    a depth within ``KINK`` of zero (there the clipped residual has no derivative); a swivel
    seed's residuals (``elbow``: the elbow's target) likewise."""
    sk, rng, dofs, q, root = _postures(seed, pick, side)
    pose = forward(sk, q, *root, with_axes=False)
    n = len(q)
    kept = ik._hand_points(sk, pose, side) + rng.normal(0.0, 0.01, (n, 5, 3))
    rest = q + rng.normal(0.0, 0.1, q.shape)
    pb = ik._Problem(root, kept, rng.uniform(0.3, 30.0, n), rest, base=pose)
    pb = replace(pb, clear_weight=clear_weight)
    if seeded:
        pb = replace(
            pb, elbow=pose.p[:, sk.joint_index(f"{side}_elbow")] + rng.normal(0, 0.1, (n, 3))
        )
    r = ik._res(sk, q, side, pb, dofs, pose)
    J = ik._jacobian(sk, q, pose, side, pb, dofs, r)
    numeric = np.empty_like(J)
    for i, d in enumerate(dofs):
        up, down = q.copy(), q.copy()
        up[:, d] += STEP
        down[:, d] -= STEP
        numeric[..., i] = (ik._res(sk, up, side, pb, dofs) - ik._res(sk, down, side, pb, dofs)) / (
            2 * STEP
        )
    compared = np.ones(J.shape[:2], dtype=bool)
    if not seeded:
        depth = clearance(sk, pose, side_limbs(side))
        compared[:, : depth.shape[1]] = np.abs(depth) > KINK
        assert np.any(depth > KINK), "some posture is inside: the depth columns are tested"
    assert np.abs(J).max() > 1.0  # the comparison is of something
    np.testing.assert_allclose(J[compared], numeric[compared], rtol=0.0, atol=1e-6)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), pick=st.integers(0, 13))
def test_dof_world_axes_are_forwards(seed: int, pick: int) -> None:
    """``dof_world_axes`` from an arm-only pose equals the axes whole-body forward kinematics
    computes, for every dof below the root."""
    sk, _, _, q, root = _postures(seed, pick, "r", n=12)
    pose = forward(sk, q, *root)
    dofs = [d for d in range(sk.n_dofs) if sk.parent[sk.dof_joint[d]] >= 0]
    np.testing.assert_allclose(
        dof_world_axes(sk, pose, q, dofs), pose.axes[:, dofs], rtol=0.0, atol=1e-14
    )


def test_an_arm_swung_into_the_trunk_comes_out_clear() -> None:
    """The left arm swung in at the shoulder, up to 3 cm into the trunk's clearance (a slow
    sweep), on every manikin, the hand free (weight 0.3) or on a goal (30): the solve leaves
    no limb's surface deeper inside a capsule than ``TOLERANCE`` (``self_intersection``, the
    check verify reports, MT0514), over 90 % of the frames not inside at all, and no frame
    deeper than it was."""
    for spec in MANIKINS:
        sk = build_manikin(spec.population, spec.sex, spec.percentile)
        n = 80
        q = np.tile(sk.q_comfort, (n, 1))
        q[:, sk.dof_index("l_shoulder_abd")] = np.linspace(-0.6, -0.2, n)
        root = (np.tile([0.0, 0.9, 0.0], (n, 1)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)))
        before = ik.penetration(sk, q, root, "l")
        rows = np.flatnonzero(before < 0.03)
        q, root, before = q[rows], (root[0][rows], root[1][rows]), before[rows]
        assert before.max() > 0.02
        for keep in (0.3, 30.0):
            out = ik.keep_clear(sk, q, root, "l", np.full(len(q), keep))
            assert np.all(ik.penetration(sk, out, root, "l") <= np.maximum(before, 0.0) + 1e-12)
            surface, _ = self_intersection(sk, forward(sk, out, *root), side_limbs("l"))
            assert surface.max() <= TOLERANCE, (spec, keep)
            assert np.mean(surface.max(axis=1) <= 0.0) > 0.9


def test_random_arms_inside_mostly_come_out() -> None:
    """Random arm postures up to 3 cm inside the clearance with the hand itself outside, on
    every manikin, both sides, the hand free: no row ends deeper than it started, and at
    least 90 % of them end with no limb's surface inside a capsule (the rest: a joint at its
    limit, or the hand's pose weighing; what is left, verify reports)."""
    surfaces = []
    for pick in range(len(MANIKINS)):
        for side in ("r", "l"):
            sk, _, _, q, root = _postures(pick, pick, side, n=600)
            depth = clearance(sk, forward(sk, q, *root, with_axes=False), side_limbs(side))
            before, hand = depth.max(axis=1), depth[:, depth.shape[1] // 2 :].max(axis=1)
            rows = np.flatnonzero((before > 0.0) & (before < 0.03) & (hand < 0.0))
            sub = (root[0][rows], root[1][rows])
            out = ik.keep_clear(sk, q[rows], sub, side, np.full(rows.size, 0.3))
            assert np.all(ik.penetration(sk, out, sub, side) <= before[rows] + 1e-12)
            surface, _ = self_intersection(sk, forward(sk, out, *sub), side_limbs(side))
            surfaces.append(surface.max(axis=1))
    inside = np.concatenate(surfaces)
    assert inside.size > 150
    assert np.mean(inside <= 0.0) >= 0.9


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), pick=st.integers(0, 13), n=st.sampled_from([1, 7, 300]))
def test_clearance_of_every_capsule_at_once_is_capsule_by_capsule(
    seed: int, pick: int, n: int
) -> None:
    """``capsules.clearance`` (all of a limb's capsules in one array) equals, to the bit, the
    depth of each sample in each capsule taken one capsule at a time (``depth_inside``, the
    loop it replaced), on random whole-body postures and roots; the deepest sample of each
    limb and capsule is the exact depth (the closest points of the two axes); its directions
    are unit or zero."""
    from mtlc.body.capsules import (
        CLEARANCE_MARGIN,
        COLUMN_SAMPLES,
        LIMB_SAMPLES,
        body_capsules,
        clearance_directions,
        closest_parameters,
        depth_inside,
        limb_axis,
        limb_radius,
        segment_distance,
    )

    sk, rng, _, q, _ = _postures(seed, pick, "l", n=n)
    q = sk.clip(q + rng.normal(0.0, 0.5, q.shape))
    pose = forward(sk, q, rng.normal(0.0, 1.0, (n, 3)), rng.normal(0.0, 1.0, (n, 4)))
    for side in ("r", "l"):
        cols = []
        exact = []
        for limb in side_limbs(side):
            p0, p1 = limb_axis(sk, pose, limb)
            for cap in body_capsules(sk):
                a, b = (
                    np.mean([pose.p[:, sk.joint_index(j)] for j in e], axis=0) for e in cap.ends
                )
                # the even samples, then the point closest to the capsule's axis
                s, _ = closest_parameters(p0, p1, a, b)
                frac = np.concatenate([np.tile(np.linspace(0.0, 1.0, LIMB_SAMPLES), (n, 1)),
                                       s[:, None]], axis=1)  # fmt: skip
                pts = p0[:, None, :] + frac[:, :, None] * (p1 - p0)[:, None, :]
                grow = limb_radius(sk, limb) + CLEARANCE_MARGIN
                cols.append(depth_inside(pts, a, b, cap.radius + grow))
                exact.append(cap.radius + grow - segment_distance(p0, p1, a, b))
        want = np.concatenate(cols, axis=1)
        # the deepest sample of each limb and capsule is the exact depth (the check's)
        deepest = want.reshape(n, len(exact), COLUMN_SAMPLES).max(axis=2)
        np.testing.assert_allclose(deepest, np.stack(exact, axis=1), atol=1e-12)
        np.testing.assert_array_equal(clearance(sk, pose, side_limbs(side)), want)
        depth, directions = clearance_directions(sk, pose, side_limbs(side))
        np.testing.assert_array_equal(depth, want)
        norms = np.linalg.norm(directions, axis=-1)
        assert np.all((np.abs(norms - 1.0) < 1e-12) | (norms == 0.0))
