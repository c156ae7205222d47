"""The smoothing and clearance passes take the balance pass's pose of the frames
(``FramesPosed``) instead of posing them again (issue 17: a long walk's 25,000 frames were
posed three times): their output must be the same to the bit as when they pose them
themselves."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from mtlc.body import forward
from mtlc.body.kinematics import output_pose
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import MOTION_PASSES, MotionOptions, PassContext, lower, run_motion, smooth
from mtlc.passes.context import FramesPosed
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("example", "sex", "pct", "corrected"),
    [("replace_fuel_filter", "female", 5, True), ("drain_hydraulic_reservoir", "male", 95, False)],
)
def test_smooth_gives_the_same_frames_from_the_balance_pose(
    example: str, sex: str, pct: int, corrected: bool
) -> None:
    """The fuel filter's kneel is corrected by balance (those frames are posed again); the
    drain's frames are all as balance measured them."""
    options = FrontendOptions(manikin=ManikinSpec("gb10000_1988", sex, pct))
    prog = run_frontend([ROOT / "examples" / f"{example}.mtask"], options)
    ctx = PassContext(prog.sink, MotionOptions())
    ir = lower(prog.timelines[0])
    for name, motion_pass in MOTION_PASSES:
        ir = motion_pass(ir, ctx)
        if name == "balance":
            break
    handed = ctx.cache.get(FramesPosed.KEY)
    assert handed is not None and sum(len(p.R) for p in handed.poses) == len(ir.frames.time)
    # where balance changed frames, the hand-off must pose those again, not take them as measured
    assert bool((handed.q != ir.frames.q).any()) == corrected
    alone = copy.deepcopy(ir)
    fresh = PassContext(DiagnosticSink(), MotionOptions())
    smooth.run(ir, ctx)
    assert ctx.cache[FramesPosed.KEY] is handed  # brought up to date, for clearance
    smooth.run(alone, fresh)
    same(ir, alone)
    # and clearance, which takes it from smooth (the carry pass between may change frames)
    for name, motion_pass in MOTION_PASSES:
        if name in ("carry", "clearance"):
            ir, alone = motion_pass(ir, ctx), motion_pass(alone, fresh)
    assert ctx.cache[FramesPosed.KEY] is not handed  # taken, and clearance's own handed on
    same(ir, alone)


def same(a: MotionIR, b: MotionIR) -> None:
    for field in ("q", "root_position", "root_rotation"):
        x, y = getattr(a.frames, field), getattr(b.frames, field)
        assert np.array_equal(x.view(np.int64), y.view(np.int64)), field


@pytest.mark.parametrize(("sex", "pct"), [("female", 5), ("male", 95)])
def test_verify_poses_the_output_frames_as_forward_does(sex: str, pct: int) -> None:
    """Verify takes clearance's pose of the dense frames (through sample: the output frames
    are every other dense frame) and poses again what changed: the pose it keeps for lint and
    the metrics is ``forward``'s, to the bit."""
    options = FrontendOptions(manikin=ManikinSpec("gb10000_1988", sex, pct))
    prog = run_frontend([ROOT / "examples" / "replace_fuel_filter.mtask"], options)
    ir = run_motion(prog.timelines[0], prog.sink)
    f = ir.frames
    kept = output_pose(ir.skeleton, f.q, f.root_position, f.root_rotation)
    want = forward(ir.skeleton, f.q, f.root_position, f.root_rotation, with_axes=False)
    assert np.array_equal(kept.R.view(np.int64), want.R.view(np.int64))
    assert np.array_equal(kept.p.view(np.int64), want.p.view(np.int64))
