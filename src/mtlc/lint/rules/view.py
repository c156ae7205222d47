"""One manikin's compiled motion as the motion rules read it: frames, poses and, for every
frame, the task line that asked for the motion then (where a finding is reported)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from mtlc.body.kinematics import Pose, output_pose
from mtlc.diagnostics import Span
from mtlc.geometry.rays import RayScene
from mtlc.ir.model import FloatArray, MotionIR, Segment
from mtlc.lint.config import LintConfig
from mtlc.lint.findings import Finding
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

    @cached_property
    def rays(self) -> RayScene | None:
        """The scene's triangles for the rules that cast rays (MT0610, MT0611), flattened once
        for all of them; None without geometry."""
        scene = RayScene(self.ir.geometry) if self.ir.geometry else None
        return scene if scene is not None and len(scene) else None

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


def segment_finding(view: MotionView, code: str, seg: Segment, msg: str, help: str) -> Finding:
    """A motion rule's finding at the task line that asked for ``seg``, for this manikin."""
    o = seg.provenance.origin
    span = Span(o.file, o.line, o.column, o.end_line, o.end_column)
    return Finding(code, msg, span, help=help, manikins=(view.manikin,), details=(msg,))


def frame_segments(ir: MotionIR, t: FloatArray) -> NDArray[np.intp]:
    """The most specific (shortest) segment covering each frame; between segments the last one
    that ended, before the first one the first.

    Memory O(frames + segments), not frames x segments: segments are laid over the frames from
    the shortest up (ties: the earlier in ``ir.segments``), each frame keeping the first that
    covers it; the last one ended is a search in the sorted ends. The result is the dense
    argmin/argmax over (frames, segments) that ``frame_segments_dense`` states."""
    start = np.array([s.start for s in ir.segments], dtype=float)
    end = np.array([s.end for s in ir.segments], dtype=float)
    t = np.asarray(t, dtype=float)
    order = np.argsort(t, kind="stable")  # frames are in time order; sort if a caller's are not
    ts = t[order]
    out = np.full(len(t), -1, dtype=np.intp)
    chosen = np.full(len(t), -1, dtype=np.intp)
    # covering: t >= start - 1e-9 and t <= end + 1e-9, the narrowest first, then the lowest index
    lo = np.searchsorted(ts, start - 1e-9, side="left")
    hi = np.searchsorted(ts, end + 1e-9, side="right")
    for j in np.lexsort((np.arange(len(start)), end - start)):
        a, b = int(lo[j]), int(hi[j])
        if a < b:
            window = chosen[a:b]
            window[window < 0] = j
    covered = chosen >= 0
    # otherwise: the first segment (by index) among those with the latest end <= t + 1e-9
    by_end = np.lexsort((np.arange(len(end)), end))
    ends = end[by_end]
    k = np.searchsorted(ends, ts + 1e-9, side="right") - 1
    first_of = np.searchsorted(ends, ends[np.maximum(k, 0)], side="left")
    last = np.where(k >= 0, by_end[first_of], int(np.argmin(start)))
    out[order] = np.where(covered, chosen, last)
    return out


def frame_segments_dense(ir: MotionIR, t: FloatArray) -> NDArray[np.intp]:
    """``frame_segments`` as a (frames, segments) mask: the definition, for tests on small
    inputs (a long motion would need gigabytes)."""
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
    # no dof axes: the rules take no Jacobian (a third of a pose's ~2.8 KB a frame)
    # the verify pass's pose of the same frames (``output_pose``)
    pose = output_pose(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    return MotionView(
        ir, manikin, config, frames.time, frames.q, pose, frame_segments(ir, frames.time), timeline
    )
