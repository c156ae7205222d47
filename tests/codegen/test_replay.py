"""Replaying generated JackScript reproduces the IR's frames; the fake js API is strict.

Every function of every example script runs (no arguments) against mtlc.codegen.replay; at
every output frame its joint angles are within 0.1 degree of the IR (0.05 degree by
construction, 1e-3 degree at the keys themselves), the root within 1 mm and 0.1 degree. With
``ta="jack"`` the same holds outside the TA windows, which Jack's IK fills.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import compiled_example

from mtlc.codegen.jack_api import DOF_MAP, EFFECTORS, JACK_API
from mtlc.codegen.jackscript import (
    ANGLE_TOLERANCE_DEG,
    emit_jackscript,
    frame_after,
    frame_before,
    to_jack_position,
)
from mtlc.codegen.replay import ReplayedMotion, ReplayError, replay
from mtlc.ir.model import MotionIR

# not imported from conftest: another tests/ folder has a conftest module of its own
ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))

ANGLE_LIMIT = math.radians(0.1)
AT_KEY_LIMIT = math.radians(1e-3)
ROOT_LIMIT = 1e-3  # m
ROTATION_LIMIT = math.radians(0.1)

SEED_SAMPLE = """from js import *
def t():
    human = CreateHuman()
    human.Walk( (200, 0, 200), duration=5)
"""


@pytest.fixture(scope="module")
def example_irs() -> list[MotionIR]:
    return [ir for path in EXAMPLES for ir in compiled_example(path).motions]


def replay_task(ir: MotionIR, ta: str) -> ReplayedMotion:
    script = emit_jackscript([ir], ta=ta)
    (function,) = script.source_map["functions"]
    return replay(script.text, function)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    dot = np.clip(np.abs(np.sum(a * b, axis=-1)), 0.0, 1.0)
    return 2.0 * np.arccos(dot)


def frame_errors(ir: MotionIR, motion: ReplayedMotion) -> tuple[np.ndarray, ...]:
    """Per frame: worst joint angle error, root distance, root rotation angle."""
    assert ir.frames is not None
    at = motion.sample(ir.frames.time)
    dq = np.abs(at.q - ir.frames.q).max(axis=1)
    dp = np.linalg.norm(at.root_position - ir.frames.root_position, axis=1)
    dr = rotation_angle(at.root_rotation, ir.frames.root_rotation)
    return dq, dp, dr


def assert_exact_at_own_keys(ir: MotionIR, motion: ReplayedMotion) -> None:
    """Each dof matches the IR to 1e-3 degree at the frames where its joint is keyed."""
    assert ir.frames is not None
    frame_times = np.round(ir.frames.time, 6)
    keyed = 0
    for column, (_, joint, index, _) in enumerate(DOF_MAP):
        keys = motion.recording.joints[joint][index].keys
        rows = np.isin(frame_times, np.round(list(keys), 6))
        keyed += int(rows.sum())
        error = np.abs(motion.sample(ir.frames.time[rows]).q[:, column] - ir.frames.q[rows, column])
        assert error.max() < AT_KEY_LIMIT, (ir.task, joint)
    assert keyed >= 2 * len(DOF_MAP)


def test_replay_reproduces_every_frame(example_irs: list[MotionIR]) -> None:
    for ir in example_irs:
        assert ir.frames is not None and ir.skeleton is not None
        motion = replay_task(ir, "keyframes")
        assert motion.dof_names == ir.skeleton.dof_names
        dq, dp, dr = frame_errors(ir, motion)
        assert dq.max() < ANGLE_LIMIT, (ir.task, math.degrees(dq.max()))
        assert dq.max() <= math.radians(ANGLE_TOLERANCE_DEG) + AT_KEY_LIMIT
        assert dp.max() < ROOT_LIMIT, (ir.task, dp.max())
        assert dr.max() < ROTATION_LIMIT, (ir.task, dr.max())
        assert_exact_at_own_keys(ir, motion)
        assert len(motion.time) < len(ir.frames.time), "decimation keeps fewer keys than frames"


def test_jack_mode_reaches_and_leaves_the_rest_exact(example_irs: list[MotionIR]) -> None:
    for ir in example_irs:
        assert ir.frames is not None
        motion = replay_task(ir, "jack")
        time = ir.frames.time
        ta = [s for s in ir.segments if s.kind == "TA" and s.goal.effector in EFFECTORS]
        reaches = [c for c in motion.calls if c[0] == JACK_API.reach]
        assert len(reaches) == len(ta) > 0
        outside = np.ones(len(time), dtype=bool)
        for segment, (_, (effector, target), timing) in zip(
            sorted(ta, key=lambda s: s.start), reaches, strict=True
        ):
            assert effector == EFFECTORS[segment.goal.effector]
            approach = segment.result.get("approach_point", segment.goal.position)
            np.testing.assert_allclose(target, to_jack_position(approach), atol=1e-3)
            assert timing["start"] == pytest.approx(segment.start, abs=1e-6)
            outside[frame_before(time, segment.start) + 1 : frame_after(time, segment.end)] = False
        dq, dp, _ = frame_errors(ir, motion)
        assert dq[outside].max() < ANGLE_LIMIT, ir.task
        assert dp.max() < ROOT_LIMIT


def test_walk_calls_follow_the_locomotion_segments(example_irs: list[MotionIR]) -> None:
    ir = example_irs[0]
    walks = [s for s in ir.segments if s.kind == "locomotion"]
    motion = replay_task(ir, "keyframes")
    recorded = motion.recording.walks
    assert len(recorded) == len(walks) > 0
    for segment, walk in zip(walks, recorded, strict=True):
        assert walk.start == pytest.approx(segment.start, abs=1e-6)
        assert walk.duration == pytest.approx(segment.end - segment.start, abs=1e-6)
        assert walk.target[1] == pytest.approx(ir.ground)


def test_seed_sample_walks_in_a_straight_line() -> None:
    motion = replay(SEED_SAMPLE, "t")
    np.testing.assert_allclose(motion.time, [0.0, 5.0])
    halfway = motion.sample([0.0, 2.5, 5.0, 9.0])
    np.testing.assert_allclose(halfway.root_position[:, [0, 2]], [[0, 0], [1, 1], [2, 2], [2, 2]])
    np.testing.assert_allclose(halfway.root_rotation, [[1, 0, 0, 0]] * 4, atol=1e-12)
    assert JACK_API.module not in sys.modules


def test_walks_without_a_start_follow_each_other() -> None:
    script = SEED_SAMPLE + "    human.Walk((200, 0, 0), duration=2)\n"
    motion = replay(script, "t").sample([5.0, 6.0, 7.0])
    np.testing.assert_allclose(motion.root_position[:, [0, 2]], [[2, 2], [2, 1], [2, 0]])


def test_keys_interpolate_linearly_and_hold() -> None:
    script = """from js import *
def t():
    human = CreateHuman()
    human.KeyJoints(1.0, {'right_elbow': (10.0, 0.0)})
    human.KeyJoints(3.0, {'right_elbow': (30.0, -20.0)})
    human.KeyRoot(0.0, (0.0, 90.0, 0.0), (90.0, 0.0, 0.0))
"""
    motion = replay(script, "t").sample([0.0, 2.0, 4.0])
    columns = [motion.dof_names.index("r_elbow_flex"), motion.dof_names.index("r_elbow_pro")]
    np.testing.assert_allclose(
        np.degrees(motion.q[:, columns]), [[10, 0], [20, -10], [30, -20]], atol=1e-9
    )
    np.testing.assert_allclose(motion.root_position[0], [0.0, 0.9, 0.0])
    yaw = math.radians(90.0) / 2
    np.testing.assert_allclose(motion.root_rotation[0], [math.cos(yaw), 0, math.sin(yaw), 0])


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("    import os\n", "may import only"),
        ("    human.KeyJoints(0.0, {'elbow': (1.0,)})\n", "unknown Jack joint"),
        ("    human.KeyJoints(0.0, {'right_elbow': (1.0,)})\n", "takes 2 angles"),
        ("    human.KeyRoot('now', (0, 0, 0), (0, 0, 0))\n", "must be a number"),
        ("    human.Reach('nose', (0, 0, 0))\n", "unknown effector"),
        ("    human.__class__\n", "not allowed"),
        ("    CreateHuman()\n", "created 2 humans"),
    ],
)
def test_replay_refuses_what_the_api_does_not_allow(body: str, message: str) -> None:
    with pytest.raises(ReplayError, match=message):
        replay(SEED_SAMPLE + body, "t")
    assert JACK_API.module not in sys.modules


def test_scripts_get_no_builtins() -> None:
    with pytest.raises(NameError):
        replay(SEED_SAMPLE + "    open('/etc/passwd')\n", "t")
    with pytest.raises(ReplayError, match="no function"):
        replay(SEED_SAMPLE, "missing")
