"""What every motion pass receives besides the IR: options, the diagnostic sink, a cache."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mtlc.body import Pose
from mtlc.body.kinematics import forward_rows_changed
from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.ir.model import FloatArray, Frames, SourceRef

DEFAULT_FPS = 30.0
# Claims a pass makes about the output frames that the verify pass confirms with a measurement
# on those frames (docs/metrics.md): a pass's own estimate (the distance to its approach point,
# its balance on the dense frames) is not what the user sees.
VERIFIED_CODES = frozenset({"MT0501", "MT0502"})
INTERNAL_FPS = 60.0  # dense frames between interpolation and sampling


@dataclass(frozen=True)
class MotionOptions:
    fps: float = DEFAULT_FPS
    walk_clip: Path | None = None  # a BVH walking clip to take the gait from


@dataclass
class PassContext:
    sink: DiagnosticSink
    options: MotionOptions = field(default_factory=MotionOptions)
    cache: dict[str, Any] = field(default_factory=dict)  # solver models and the like, per compile
    # a pass's reports of VERIFIED_CODES, held for the verify pass: (code, message, ref, kw)
    claims: list[tuple[str, str, SourceRef, dict[str, Any]]] = field(default_factory=list)

    def report(self, code: str, message: str, ref: SourceRef, **kw: Any) -> None:
        """Report at a segment's source position (passes know SourceRefs, not AST spans).

        A code in ``VERIFIED_CODES`` is held as a claim: the verify pass reports it with the
        figure measured on the output frames (``flush_claims`` reports what verify did not)."""
        if code in VERIFIED_CODES:
            self.claims.append((code, message, ref, kw))
            return
        self.emit(code, message, ref, **kw)

    def emit(self, code: str, message: str, ref: SourceRef, **kw: Any) -> None:
        """Report now, whatever the code (the verify pass's own findings)."""
        span = Span(ref.file, ref.line, ref.column, ref.end_line, ref.end_column)
        self.sink.report(code, message, span, **kw)

    def flush_claims(self) -> None:
        """Report the held claims as the passes worded them (the run stopped before verify)."""
        for code, message, ref, kw in self.claims:
            self.emit(code, message, ref, **kw)
        self.claims.clear()


@dataclass
class FramesPosed:
    """The dense frames as one pass last posed them (``forward`` without axes, in consecutive
    chunks), handed to a later pass in ``PassContext.cache`` under ``KEY``: balance poses
    every frame, then smoothing and clearance pose the same frames again, and each changes
    few of them (a long walk's 25,000 frames were posed three times). The taker brings the
    pose up to date with ``forward_rows_changed``: the same numbers as posing anew."""

    KEY = "frames_posed"
    # frames up to which a pass keeps the pose of every frame to hand on: the default motion
    # budget's 15 minutes at 60 frames a second (a longer motion is posed by each pass again,
    # a chunk at a time: memory stays linear and small, docs/passes.md "Memory")
    MAX_FRAMES = 54_000
    q: FloatArray
    root_position: FloatArray
    root_rotation: FloatArray
    poses: list[Pose]

    @staticmethod
    def of(frames: Frames, poses: list[Pose]) -> FramesPosed:
        """``frames`` as they are now (copied), posed by ``poses`` (filled by the caller)."""
        return FramesPosed(
            frames.q.copy(), frames.root_position.copy(), frames.root_rotation.copy(), poses
        )

    @staticmethod
    def take(cache: dict[str, Any], frames: Frames) -> FramesPosed | None:
        """The handed pose, if it poses as many frames as ``frames`` has; taken once."""
        handed = cache.pop(FramesPosed.KEY, None)
        if handed is None or handed.q.shape != frames.q.shape:
            return None
        return handed  # type: ignore[no-any-return]

    def _chunks(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        starts = np.cumsum([0] + [len(p.R) for p in self.poses])
        return starts, np.searchsorted(starts, rows, side="right") - 1

    def rows(self, rows: np.ndarray) -> Pose:
        """The pose of the frames ``rows`` (ascending), as posed."""
        starts, at = self._chunks(rows)
        return Pose.joined([self.poses[k].rows(rows[at == k] - starts[k]) for k in np.unique(at)])

    def now(
        self, skel: Any, rows: np.ndarray, q: FloatArray, root: FloatArray, rot: FloatArray
    ) -> Pose:
        """The pose of the frames ``rows`` whose values are now ``q``, ``root`` and ``rot``
        (one row each): what changed since they were posed is posed again
        (``forward_rows_changed``)."""
        return forward_rows_changed(
            skel, self.rows(rows), self.q[rows], self.root_position[rows], q, root, rot,
            self.root_rotation[rows],
        )  # fmt: skip

    def all_now(self, skel: Any, frames: Frames) -> Pose:
        """``now`` of every frame of ``frames``."""
        return self.now(skel, np.arange(len(frames.q)), frames.q, frames.root_position,
                        frames.root_rotation)  # fmt: skip

    def update(self, rows: np.ndarray, pose: Pose, frames: Frames) -> None:
        """Record ``pose`` as the pose of ``frames``' rows ``rows`` (ascending) now."""
        starts, at = self._chunks(rows)
        for k in np.unique(at):
            sel = at == k
            r = rows[sel] - starts[k]
            self.poses[k].R[r], self.poses[k].p[r] = pose.R[sel], pose.p[sel]
            self.poses[k].root[r] = pose.root[sel]
        self.q[rows] = frames.q[rows]
        self.root_position[rows] = frames.root_position[rows]
        self.root_rotation[rows] = frames.root_rotation[rows]
