"""The head aim (``mtlc.body.ik.aim``): the eye line on the target where the neck can put it,
the neck at its limits where it cannot, never outside them."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward_part, site_direction, site_positions
from mtlc.body.ik.aim import aim_head, head_chain, head_yaw
from mtlc.body.skeleton import Skeleton

ONE_DEG = math.radians(1.0)
LIMIT = 1e-9  # rad: within the limits
AT_LIMIT = 1e-3  # rad: at a limit

manikins = st.builds(
    build_manikin,
    st.just("gb10000_1988"),
    st.sampled_from(["female", "male"]),
    st.sampled_from([1, 5, 10, 50, 90, 95, 99]),
)
trunks = st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6)  # lumbar and thorax dofs
headings = st.floats(-math.pi, math.pi)


def body(skel: Skeleton, trunk: list[float], heading: float) -> tuple[np.ndarray, ...]:
    """One pose (1, D): the comfortable posture with the trunk bent and turned, and its root."""
    q = skel.q_comfort.copy()
    q[:6] = np.clip(trunk, skel.lower[:6], skel.upper[:6])
    root_p = skel.root_position[None]
    root_r = np.array([[math.cos(heading / 2), 0.0, math.sin(heading / 2), 0.0]])
    return q[None], root_p, root_r


def look(skel: Skeleton, q: np.ndarray, root_p: np.ndarray, root_r: np.ndarray) -> tuple:
    pose = forward_part(skel, q, root_p, root_r, ["gaze"])
    return site_positions(skel, pose, "gaze")[0], site_direction(skel, pose, "gaze")[0]


def error(skel: Skeleton, q: np.ndarray, root_p: np.ndarray, root_r: np.ndarray, t: np.ndarray):
    eye, direction = look(skel, q, root_p, root_r)
    line = (t - eye) / np.linalg.norm(t - eye)
    return math.acos(max(-1.0, min(1.0, float(direction @ line))))


def within_limits(skel: Skeleton, q: np.ndarray) -> bool:
    return bool((q >= skel.lower - LIMIT).all() and (q <= skel.upper + LIMIT).all())


@settings(max_examples=60, deadline=None)
@given(
    manikins,
    trunks,
    headings,
    st.floats(0.0, 0.95),
    st.floats(0.0, 0.95),
    st.booleans(),
    st.booleans(),
    st.floats(0.25, 3.0),
)
def test_a_target_the_neck_can_face_is_on_the_eye_line(
    skel: Skeleton,
    trunk: list[float],
    heading: float,
    turn: float,
    nod: float,
    left: bool,
    down: bool,
    distance: float,
) -> None:
    """Targets made by a head inside its range (up to 95 % of the turn and the nod), any
    distance from 25 cm: aimed at from the head facing ahead, within 1 deg."""
    chain = head_chain(skel)
    q, root_p, root_r = body(skel, trunk, heading)
    x = np.array([[chain.aim.upper[0] * turn if left else chain.aim.lower[0] * turn,
                   chain.aim.upper[1] * nod if down else chain.aim.lower[1] * nod]])  # fmt: skip
    made = q.copy()
    made[:, chain.dofs] = chain.aim.angles(x)[0]
    eye, direction = look(skel, made, root_p, root_r)
    target = eye + distance * direction
    aimed = aim_head(skel, q, root_p, root_r, target[None])
    assert error(skel, aimed, root_p, root_r, target) <= ONE_DEG
    assert within_limits(skel, aimed[0])
    # only the neck and head move
    others = np.ones(skel.n_dofs, dtype=bool)
    others[chain.dofs] = False
    assert np.array_equal(aimed[0, others], q[0, others])


def at_limits(skel: Skeleton, q: np.ndarray) -> int:
    """How many of the neck's and head's dofs sit at one of their limits."""
    dofs = head_chain(skel).dofs
    lo, hi = skel.lower[dofs], skel.upper[dofs]
    return int(((np.abs(q[dofs] - lo) <= AT_LIMIT) | (np.abs(q[dofs] - hi) <= AT_LIMIT)).sum())


def assert_seen_or_at_limits(skel: Skeleton, aimed: np.ndarray, missed: float) -> None:
    """Past one dof's range the others may still bring the target into view (turned and tilted,
    the neck sees further than turned alone); where they cannot, the neck and head rest against
    their limits: an aim off the target with every dof inside its range could still come closer
    (the solver stops where the limits stop it)."""
    assert within_limits(skel, aimed[0])
    assert missed <= ONE_DEG or at_limits(skel, aimed[0]) >= 1


@settings(max_examples=40, deadline=None)
@given(manikins, headings, st.floats(10.0, 100.0), st.booleans(), st.floats(0.4, 3.0))
def test_a_target_past_the_turn_is_seen_or_leaves_the_neck_at_its_limits(
    skel: Skeleton, heading: float, past: float, left: bool, distance: float
) -> None:
    """Level targets 10 to 100 deg past the neck's rotation (the trunk upright)."""
    chain = head_chain(skel)
    q, root_p, root_r = body(skel, [0.0] * 6, heading)
    eye, _ = look(skel, q, root_p, root_r)
    limit = chain.aim.upper[0] if left else chain.aim.lower[0]
    yaw = limit + math.copysign(math.radians(past), limit) + heading
    target = eye + distance * np.array([math.sin(yaw), 0.0, math.cos(yaw)])
    aimed = aim_head(skel, q, root_p, root_r, target[None])
    assert_seen_or_at_limits(skel, aimed, error(skel, aimed, root_p, root_r, target))
    assert float(head_yaw(skel, aimed)[0]) * limit > 0  # turned to the target's side


@settings(max_examples=40, deadline=None)
@given(manikins, headings, st.floats(10.0, 35.0), st.floats(0.4, 3.0))
def test_a_target_past_the_nod_is_seen_or_leaves_the_neck_at_its_limits(
    skel: Skeleton, heading: float, past: float, distance: float
) -> None:
    """Targets straight ahead and below, 10 to 35 deg past the neck's and head's flexion (the
    trunk upright)."""
    chain = head_chain(skel)
    q, root_p, root_r = body(skel, [0.0] * 6, heading)
    eye, _ = look(skel, q, root_p, root_r)
    pitch = chain.aim.upper[1] + math.radians(past)
    ahead = np.array([math.sin(heading), 0.0, math.cos(heading)])
    target = eye + distance * (math.cos(pitch) * ahead - math.sin(pitch) * np.array([0, 1.0, 0]))
    aimed = aim_head(skel, q, root_p, root_r, target[None])
    assert_seen_or_at_limits(skel, aimed, error(skel, aimed, root_p, root_r, target))


@settings(max_examples=40, deadline=None)
@given(
    manikins,
    trunks,
    headings,
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    st.floats(0.3, 3.0),
)
def test_the_aim_is_never_worse_than_the_line_of_sight_clamped(
    skel: Skeleton,
    trunk: list[float],
    heading: float,
    direction: list[float],
    distance: float,
) -> None:
    """Any target around the head: no worse than turning and nodding toward it as far as the
    limits allow (the first guess, clamped), and within the limits."""
    chain = head_chain(skel)
    q, root_p, root_r = body(skel, trunk, heading)
    eye, _ = look(skel, q, root_p, root_r)
    d = np.asarray(direction, dtype=float)
    if np.linalg.norm(d) < 1e-3:
        d = np.array([0.0, 0.0, 1.0])
    target = eye + distance * d / np.linalg.norm(d)
    aimed = aim_head(skel, q, root_p, root_r, target[None])
    assert within_limits(skel, aimed[0])
    pose = forward_part(skel, q, root_p, root_r, ["gaze"])
    base_R = pose.R[:, chain.base]
    u = base_R[0].T @ (target - eye)
    clamped = np.clip(
        [[math.atan2(u[0], u[2]), math.atan2(-u[1], math.hypot(u[0], u[2]))]],
        chain.aim.lower,
        chain.aim.upper,
    )
    simple = q.copy()
    simple[:, chain.dofs] = chain.aim.angles(clamped)[0]
    assert (
        error(skel, aimed, root_p, root_r, target)
        <= error(skel, simple, root_p, root_r, target) + 1e-9
    )


def test_rows_are_solved_alone_or_together_alike() -> None:
    """The batch changes no row: each row's aim is what it is when solved on its own."""
    skel = build_manikin("gb10000_1988", "female", 5)
    rng = np.random.default_rng(7)
    q = np.tile(skel.q_comfort, (40, 1))
    q[:, :6] += rng.uniform(-0.3, 0.3, (40, 6))
    root_p = np.tile(skel.root_position, (40, 1))
    root_r = np.tile([1.0, 0.0, 0.0, 0.0], (40, 1))
    targets = rng.uniform([-1.5, 0.0, -1.5], [1.5, 2.0, 1.5], (40, 3))
    together = aim_head(skel, q, root_p, root_r, targets)
    alone = np.vstack(
        [aim_head(skel, q[i : i + 1], root_p[i : i + 1], root_r[i : i + 1], targets[i : i + 1])
         for i in range(40)]
    )  # fmt: skip
    assert np.allclose(together, alone, atol=1e-9)
