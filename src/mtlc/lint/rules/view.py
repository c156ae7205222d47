"""One manikin's compiled motion as the motion rules read it: frames, poses and, for every
frame, the task line that asked for the motion then (where a finding is reported)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mtlc.body import forward
from mtlc.body.kinematics import Pose
from mtlc.diagnostics import Span
from mtlc.ir.model import FloatArray, MotionIR, Segment
from mtlc.lint.config import LintConfig
from mtlc.semantics.timeline import Timeline


@dataclass
class MotionView:
    ir: MotionIR
    manikin: str  # POP:SEX:PCT
    config: LintConfig
    time: FloatArray  # (N,)
    q: FloatArray  # (N, D)
    pose: Pose
    frame_segment: NDArray[np.intp]  # (N,) index into ir.segments
    timeline: Timeline | None = None  # the primitives' arguments (a lift's load) the IR drops

    def segment(self, frame: int) -> Segment:
        return self.ir.segments[int(self.frame_segment[frame])]

    def span(self, frame: int) -> Span:
        o = self.segment(frame).provenance.origin
        return Span(o.file, o.line, o.column, o.end_line, o.end_column)

    def where(self, frame: int) -> str:
        return " > ".join(self.segment(frame).provenance.path)

    def worst_per_line(self, bad: NDArray[np.bool_], value: FloatArray) -> list[int]:
        """For each task line with bad frames, the frame where ``value`` is largest."""
        best: dict[Span, int] = {}
        for i in np.flatnonzero(bad):
            key = self.span(int(i))
            if key not in best or value[i] > value[best[key]]:
                best[key] = int(i)
        return sorted(best.values())


def frame_segments(ir: MotionIR, t: FloatArray) -> NDArray[np.intp]:
    """The most specific (shortest) segment covering each frame; between segments the last one
    that ended, before the first one the first."""
    start = np.array([s.start for s in ir.segments])
    end = np.array([s.end for s in ir.segments])
    covers = (t[:, None] >= start - 1e-9) & (t[:, None] <= end + 1e-9)  # (N, S)
    width = np.where(covers, end - start, np.inf)
    inside = np.argmin(width, axis=1)
    ended = np.where(end[None, :] <= t[:, None] + 1e-9, end[None, :], -np.inf)
    last = np.argmax(ended, axis=1)
    fallback = np.where(np.isfinite(ended.max(axis=1)), last, int(np.argmin(start)))
    return np.where(covers.any(axis=1), inside, fallback).astype(np.intp)


def make_view(
    ir: MotionIR, manikin: str, config: LintConfig, timeline: Timeline | None = None
) -> MotionView | None:
    frames = ir.frames
    if frames is None or ir.skeleton is None or len(frames.time) == 0 or not ir.segments:
        return None
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    return MotionView(
        ir, manikin, config, frames.time, frames.q, pose, frame_segments(ir, frames.time), timeline
    )
