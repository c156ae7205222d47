"""The gaze, pace and interpolation passes' fast paths give what the straightforward code gave
(issue 21): each is compared with the code it replaced, kept here as the reference."""

from __future__ import annotations

import copy
import itertools
from pathlib import Path

import numpy as np
import pytest
from conftest import example_until
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.ir.model import Frames, GoalSpec, MotionIR, Segment
from mtlc.passes import gaze
from mtlc.passes.context import PassContext
from mtlc.passes.interpolate import (
    _feet_in_root_frame,
    correct_base,
    feet_summary_rows,
    interpolate_joints,
    interpolate_root,
    keyed_windows,
)
from mtlc.passes.pace import Movement, _shares_dofs, movements
from mtlc.passes.state import PoseState

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ["drain_hydraulic_reservoir", "replace_fuel_filter", "remove_access_panel"]


def compiled_until(name: str, until: str) -> tuple[MotionIR, PassContext]:
    ir, sink = example_until(ROOT / "examples" / f"{name}.mtask", until)
    return ir, PassContext(sink)


# -- gaze --------------------------------------------------------------------------------------


def insert_walking_back(segments: list[Segment], seg: Segment) -> None:
    """The reference: walk back from the end past every segment that starts later."""
    at = len(segments)
    while at > 0 and segments[at - 1].start > seg.start + gaze.EPS:
        at -= 1
    segments.insert(at, seg)


def segment(start: float) -> Segment:
    return Segment("head", "gaze", start, start + 1.0, GoalSpec("gaze"), None)  # type: ignore[arg-type]


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(0.0, 10.0, allow_nan=False), max_size=30),
    st.floats(-1.0, 11.0, allow_nan=False),
)
def test_insert_in_time_order_is_the_walk_back(starts: list[float], new: float) -> None:
    """Also on a list that is not sorted (a look's start is moved earlier in place)."""
    listed = [segment(s) for s in starts]
    fast, slow = list(listed), list(listed)
    seg = segment(new)
    gaze.insert_in_time_order(fast, seg)
    insert_walking_back(slow, seg)
    assert [id(s) for s in fast] == [id(s) for s in slow]


def keep_pace_key_by_key(ir: MotionIR, state: PoseState) -> None:
    """The reference sweep (before issue 21): every key visited, its errors one time at a time."""
    heads = [s for s in ir.segments if s.track == "head" and s.keyframes is not None]
    keys = sorted(
        (round(float(t), 9), n, i)
        for n, s in enumerate(heads)
        for i, t in enumerate(s.keyframes.time)  # type: ignore[union-attr]
    )
    changed: set[int] = set()
    last_t, last_q = 0.0, None

    def errors(seg: Segment, times: np.ndarray, poses: np.ndarray) -> np.ndarray:
        body = np.array([state.q_at(float(t)) for t in times])
        body[:, [ir.skeleton.dof_index(n) for n in seg.keyframes.dofs]] = poses  # type: ignore[union-attr]
        roots = [state.root_at(float(t)) for t in times]
        target = np.tile(np.asarray(seg.goal.position, dtype=float), (len(body), 1))
        return gaze.aim_errors(
            ir.skeleton, body, np.array([r[0] for r in roots]), np.array([r[1] for r in roots]),
            target,
        )  # fmt: skip

    for t, n, i in keys:
        q = heads[n].keyframes.q  # type: ignore[union-attr]
        if last_q is not None:
            if i == 0:
                kept = last_q
            else:
                room = gaze.HEAD_PACE * max(t - last_t, 0.0)
                kept = np.clip(q[i], last_q - room, last_q + room)
                if np.abs(kept - q[i]).max() > 1e-12 and heads[n].goal.position is not None:
                    options = (kept, last_q)
                    e = errors(heads[n], np.full(2, t), np.stack(options))
                    kept = options[int(np.argmin(e))]
            if np.abs(kept - q[i]).max() > 1e-12:
                q[i] = kept
                changed.add(n)
        last_t, last_q = t, q[i].copy()
    for n in sorted(changed):
        seg = heads[n]
        if seg.goal.position is None:
            continue
        kf = seg.keyframes
        e = errors(seg, kf.time, kf.q)  # type: ignore[union-attr]
        worst = float(e[1:].max() if seg.goal.params.get("implicit") else e[-1])
        seg.result = {**seg.result, "angle_error": worst, "success": worst <= gaze.GAZE_TOLERANCE}


@pytest.mark.parametrize("name", EXAMPLES)
def test_keep_pace_is_the_key_by_key_sweep(name: str) -> None:
    ir, ctx = compiled_until(name, "tool")
    state = PoseState(ir)
    looks = gaze.solve_looks(ir, ctx, state)
    gaze.follow_the_work(ir, ctx, state, looks)
    gaze.face_ahead(ir, ctx, state)
    # pull a few head keys apart so that the sweep has keys to change
    heads = [s for s in ir.segments if s.track == "head" and s.keyframes is not None]
    for seg in heads[::2]:
        kf = seg.keyframes
        assert kf is not None
        kf.q[len(kf.q) // 2] += 0.6
    ref_ir, ref_state = copy.deepcopy((ir, state))
    before = [s.keyframes.q.copy() for s in heads]  # type: ignore[union-attr]
    gaze.keep_pace(ir, ctx, state)
    assert any(not np.array_equal(b, s.keyframes.q) for b, s in zip(before, heads, strict=True))  # type: ignore[union-attr]
    keep_pace_key_by_key(ref_ir, ref_state)
    mine = [s for s in ir.segments if s.track == "head"]
    ref = [s for s in ref_ir.segments if s.track == "head"]
    assert len(mine) == len(ref) and mine
    for a, b in zip(mine, ref, strict=True):
        np.testing.assert_array_equal(a.keyframes.q, b.keyframes.q)  # type: ignore[union-attr]
        assert a.result == b.result


# -- pace --------------------------------------------------------------------------------------


def shares_dofs_by_scan(ir: MotionIR, m: Movement) -> bool:
    """The reference: every segment's keyframes tested against the movement's window."""
    mine = set(m.dofs)
    for s in ir.segments:
        kf = s.keyframes
        if any(s is x for x in m.segments) or kf is None or not mine.intersection(kf.dofs):
            continue
        if np.any((kf.time > m.start + 1e-6) & (kf.time < m.end - 1e-6)):
            return True
    return False


@pytest.mark.parametrize("name", EXAMPLES)
def test_shares_dofs_is_the_scan(name: str) -> None:
    ir, _ = compiled_until(name, "gaze")
    kept = movements(ir)
    assert kept
    # the kept movements share no dof; make some that do, from every pair of reaches
    candidates = list(kept)
    reaches = [s for s in ir.segments if s.kind in ("TA", "TO") and s.keyframes is not None]
    for a, b in itertools.pairwise(reaches):
        candidates.append(Movement([a], a.start, b.end))
        candidates.append(Movement([a, b], a.start - 0.5, b.end + 0.5))
    verdicts = [_shares_dofs(ir, m) for m in candidates]
    assert verdicts == [shares_dofs_by_scan(ir, m) for m in candidates]
    assert any(verdicts) and not any(verdicts[: len(kept)])


# -- interpolation -----------------------------------------------------------------------------


def correct_base_whole(ir: MotionIR, frames: Frames) -> None:
    """The reference base correction: every frame's foot points, then anchored."""
    from mtlc.passes.interpolate import _anchor, keyed_root, walking_mask

    walking = walking_mask(ir, frames.time)
    standing = ~walking & ~keyed_root(ir, frames.time)[0]
    feet = _feet_in_root_frame(ir.skeleton, frames.q, frames.root_rotation)
    centre, lowest = feet.mean(axis=1), feet[..., 1].min(axis=1)
    if standing.any():
        plan_position, _ = ir.root_plan.at(frames.time[standing])  # type: ignore[union-attr]
        frames.root_position[standing] = _anchor(
            ir.skeleton, centre[standing], lowest[standing], plan_position,
            frames.root_rotation[standing], ir.ground,
        )  # fmt: skip
    if walking.any():
        low = frames.root_position[walking, 1] + lowest[walking]
        frames.root_position[walking, 1] += np.maximum(ir.ground - low, 0.0)


@pytest.mark.parametrize("name", EXAMPLES)
def test_correct_base_is_the_whole_pose_correction(name: str) -> None:
    """Frames whose legs do not move share one computation; the numbers are every frame's."""
    ir, _ = compiled_until(name, "pace")
    grid = np.linspace(0.0, ir.duration, 5000)
    position, rotation = interpolate_root(ir, grid)
    fast = Frames(0.0, grid, position.copy(), rotation, interpolate_joints(ir, grid))
    slow = Frames(0.0, grid, position.copy(), rotation, fast.q)
    correct_base(ir, fast)
    correct_base_whole(ir, slow)
    np.testing.assert_array_equal(fast.root_position, slow.root_position)
    centre, lowest = feet_summary_rows(ir.skeleton, fast.q, rotation)
    legs_still = (fast.q[1:] == fast.q[:-1]).all(axis=1).sum()
    assert legs_still > 0  # the shortcut was taken
    feet = _feet_in_root_frame(ir.skeleton, fast.q, rotation)
    np.testing.assert_array_equal(lowest, feet[..., 1].min(axis=1))
    np.testing.assert_array_equal(centre, feet.mean(axis=1))


def keyed_windows_by_scan(ir: MotionIR) -> list[tuple[Segment, float, float]]:
    movers = sorted(
        (s for s in ir.segments if s.kind == "locomotion"
         or (s.kind == "posture" and s.keyframes is not None
             and s.keyframes.root_position is not None)),
        key=lambda s: s.start,
    )  # fmt: skip
    out = []
    for i, seg in enumerate(movers):
        if seg.kind == "posture" and seg.result.get("root") == "keyed":
            nxt = [m.start for m in movers[i + 1 :] if m.start > seg.start + 1e-9]
            out.append((seg, seg.start, min(nxt, default=np.inf)))
    return out


@pytest.mark.parametrize("name", EXAMPLES)
def test_keyed_windows_by_bisection_is_the_scan(name: str) -> None:
    ir, _ = compiled_until(name, "gaze")
    fast, slow = keyed_windows(ir), keyed_windows_by_scan(ir)
    assert [(id(s), a, b) for s, a, b in fast] == [(id(s), a, b) for s, a, b in slow]
    if name == "replace_fuel_filter":
        assert fast  # its stepping kneel places the root
