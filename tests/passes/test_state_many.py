"""The pose state's batch queries (``q_at_many``, ``root_at_many``) give the per-time answers
bit for bit: the gaze pass and its tests read the body through them (issue 21's speed-up must
change no output)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import example_until

from mtlc.ir.model import MotionIR
from mtlc.passes.state import PoseState

ROOT = Path(__file__).resolve().parents[2]
# a walk, a squat and a stepping kneel (keyed root) between them
EXAMPLES = ["drain_hydraulic_reservoir", "replace_fuel_filter", "remove_access_panel"]


@pytest.fixture(scope="module", params=EXAMPLES)
def solved_ir(request: pytest.FixtureRequest) -> MotionIR:
    ir, _ = example_until(ROOT / "examples" / f"{request.param}.mtask", "gaze")
    return ir


KEY_TIMES = 400  # keyframe times probed at most (evenly spread): the wrench's strokes have 4,000


def probe_times(ir: MotionIR) -> np.ndarray:
    """Every segment's ends and up to ``KEY_TIMES`` keyframe times, a hair either side, and
    an even grid."""
    times = [0.0, ir.duration]
    keys: list[float] = []
    for seg in ir.segments:
        times += [seg.start, seg.end]
        if seg.keyframes is not None:
            keys += [float(t) for t in seg.keyframes.time]
    keys = sorted(set(keys))
    pick = np.unique(np.linspace(0, len(keys) - 1, min(len(keys), KEY_TIMES)).round().astype(int))
    base = np.array(times + [keys[i] for i in pick])
    grid = np.linspace(0.0, ir.duration, 301)
    return np.concatenate([base, base - 1e-9, base + 1e-9, base + 2e-9, grid])


def test_q_at_many_is_q_at(solved_ir: MotionIR) -> None:
    state = PoseState(solved_ir)
    times = probe_times(solved_ir)
    many = state.q_at_many(times)
    one = np.array([state.q_at(float(t)) for t in times])
    assert many.shape == (len(times), solved_ir.skeleton.n_dofs)
    np.testing.assert_array_equal(many, one)


def test_q_at_many_skips_like_q_at(solved_ir: MotionIR) -> None:
    state = PoseState(solved_ir)
    times = probe_times(solved_ir)
    keyed = [s for s in solved_ir.segments if s.keyframes is not None]
    for skip in (keyed[::3], keyed[1], keyed[-4:]):
        many = state.q_at_many(times, skip=skip)
        one = np.array([state.q_at(float(t), skip=skip) for t in times])
        np.testing.assert_array_equal(many, one)


def test_root_at_many_is_root_at(solved_ir: MotionIR) -> None:
    state = PoseState(solved_ir)
    times = probe_times(solved_ir)
    position, rotation = state.root_at_many(times)
    roots = [state.root_at(float(t)) for t in times]
    np.testing.assert_array_equal(position, np.array([r[0] for r in roots]))
    np.testing.assert_array_equal(rotation, np.array([r[1] for r in roots]))
    walks_or_kneels = [
        s for s in solved_ir.segments if s.kind == "locomotion" or s.result.get("root") == "keyed"
    ]
    assert walks_or_kneels  # the examples exercise the gait's and the keyed root too


def test_root_at_many_skips_like_root_at(solved_ir: MotionIR) -> None:
    state = PoseState(solved_ir)
    times = probe_times(solved_ir)[::3]
    skip = [s for s in solved_ir.segments if s.kind == "posture"]
    position, rotation = state.root_at_many(times, skip=skip)
    roots = [state.root_at(float(t), skip=skip) for t in times]
    np.testing.assert_array_equal(position, np.array([r[0] for r in roots]))
    np.testing.assert_array_equal(rotation, np.array([r[1] for r in roots]))


def test_the_batch_sees_keyframes_added_and_rewritten(solved_ir: MotionIR) -> None:
    """The arrays behind the batch are rebuilt when a segment is indexed, and read the
    keyframes' values afresh (``reanchor`` rewrites them in place)."""
    state = PoseState(solved_ir)
    times = probe_times(solved_ir)
    state.q_at_many(times)  # builds the arrays
    seg = next(s for s in solved_ir.segments if s.keyframes is not None and len(s.keyframes.q))
    seg.keyframes.q[0] += 0.01  # type: ignore[union-attr]
    np.testing.assert_array_equal(
        state.q_at_many(times), np.array([state.q_at(float(t)) for t in times])
    )
    seg.keyframes.q[0] -= 0.01  # type: ignore[union-attr]
    before = state.q_at_many(times)
    late = next(s for s in reversed(solved_ir.segments) if s.track == "head" and s.keyframes)
    late.keyframes.q = late.keyframes.q + 0.02  # type: ignore[union-attr]
    state.add(late)  # indexed again: its keys now win at their times
    after = state.q_at_many(times)
    np.testing.assert_array_equal(after, np.array([state.q_at(float(t)) for t in times]))
    assert not np.array_equal(before, after)
