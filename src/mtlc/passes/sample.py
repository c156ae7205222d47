"""Pass 8: resample the corrected dense frames at the output rate (default 30 fps, --fps)."""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import Frames, MotionIR
from mtlc.passes.context import PassContext
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
        ir.frames = resample(ir.frames, ctx.options.fps)
    return ir
