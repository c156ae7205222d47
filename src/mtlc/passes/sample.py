"""Pass 8: resample the corrected dense frames at the output rate (default 30 fps, --fps)."""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import Frames, MotionIR
from mtlc.passes.context import FramesPosed, PassContext
from mtlc.passes.interpolate import time_grid


def resample(frames: Frames, fps: float) -> Frames:
    grid = time_grid(float(frames.time[-1]), fps)

    def lerp(values: np.ndarray) -> np.ndarray:
        return np.stack(
            [np.interp(grid, frames.time, values[:, i]) for i in range(values.shape[1])], axis=1
        )

    rotation = lerp(frames.root_rotation)  # neighbouring frames: a normalised lerp is a slerp
    rotation /= np.linalg.norm(rotation, axis=1, keepdims=True)
    return Frames(
        fps=fps,
        time=grid,
        root_position=lerp(frames.root_position),
        root_rotation=rotation,
        q=lerp(frames.q),
    )


def run(ir: MotionIR, ctx: PassContext) -> MotionIR:
    if ir.frames is not None and len(ir.frames.time):
        dense = ir.frames
        handed = FramesPosed.take(ctx.cache, dense)
        ir.frames = resample(dense, ctx.options.fps)
        if handed is not None:
            _hand_on(ctx, handed, dense, ir.frames)
    return ir


def _hand_on(ctx: PassContext, handed: FramesPosed, dense: Frames, out: Frames) -> None:
    """Hand the dense frames' pose on to verify for the output frames at the dense frames'
    own instants (at the default rates every one: 30 fps of 60; the interpolation is then the
    dense frame to the bit, and verify poses again whatever differs)."""
    at = np.minimum(np.searchsorted(dense.time, out.time), len(dense.time) - 1)
    if not np.array_equal(dense.time[at], out.time):
        return
    ctx.cache[FramesPosed.KEY] = FramesPosed(
        handed.q[at], handed.root_position[at], handed.root_rotation[at], [handed.rows(at)]
    )
