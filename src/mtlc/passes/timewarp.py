"""A monotone re-mapping of the whole keyframe IR's clock: some windows last longer.

The timeline gives each action its MTM time; a reach whose arm must swing further than a person's
joint speed allows in that time is given more (the pace pass decides how much). Everything on the
clock then moves with it: inside a stretched window every time is scaled about the window's start,
after it every time is delayed by the added time, so what ran alongside the movement (the other
hand, the gaze, a hold) keeps its place relative to it and what came after starts after it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mtlc.ir.model import FloatArray, MotionIR

# result entries that hold times (s): footsteps' and kneel phases', rolls', the gait's end
TIME_KEYS = frozenset({"start", "end", "from", "to", "feet_held_until"})
# result entries that map names to [start, end] lists of times: a wrench stroke's phases
TIME_SPAN_KEYS = frozenset({"phases"})


@dataclass(frozen=True)
class Stretch:
    """The window ``start``..``end`` (on the clock before the warp) lasts ``extra`` s longer."""

    start: float
    end: float
    extra: float


@dataclass(frozen=True)
class TimeWarp:
    """Piecewise linear and increasing: ``old`` knots go to ``new`` knots; past the last knot
    a time is delayed by the total added time."""

    old: FloatArray
    new: FloatArray

    @classmethod
    def of(cls, stretches: list[Stretch]) -> TimeWarp:
        """The warp of windows that do not overlap (a later one overlapping an earlier one is
        left out)."""
        old, new = [0.0], [0.0]
        for s in sorted(stretches, key=lambda s: s.start):
            if s.start < old[-1] - 1e-9 or s.extra <= 0.0:
                continue
            shift = new[-1] - old[-1]
            old += [s.start, s.end]
            new += [s.start + shift, s.end + shift + s.extra]
        return cls(np.asarray(old), np.asarray(new))

    @property
    def total(self) -> float:
        return float(self.new[-1] - self.old[-1])

    def __call__(self, t: FloatArray | float) -> Any:
        tt = np.asarray(t, dtype=float)
        out = np.where(tt >= self.old[-1], tt + self.total, np.interp(tt, self.old, self.new))
        return float(out) if out.ndim == 0 else out


def warp_result(value: Any, warp: TimeWarp, key: str = "") -> Any:
    """A segment's result with its times warped (floats under time keys, in nested lists and
    dicts; positions and other numbers unchanged)."""
    if isinstance(value, dict):
        if key in TIME_SPAN_KEYS:  # {"seat": [t0, t1], ...}
            return {k: _warp_span(v, warp) for k, v in value.items()}
        return {k: warp_result(v, warp, str(k)) for k, v in value.items()}
    if isinstance(value, list):
        return [warp_result(v, warp) for v in value] if key not in TIME_KEYS else value
    if isinstance(value, float) and (key in TIME_KEYS or key.startswith("t_")):
        return round(warp(value), 9)
    return value


def _warp_span(value: Any, warp: TimeWarp) -> Any:
    if isinstance(value, list) and all(isinstance(v, float) for v in value):
        return [round(warp(v), 9) for v in value]
    return value


def apply(ir: MotionIR, warp: TimeWarp) -> None:
    """Every time the IR holds, warped in place: segments' windows and keyframes, their
    results' times and the root plan's knots."""
    if warp.total <= 0.0:
        return
    for seg in ir.segments:
        seg.start, seg.end = warp(seg.start), warp(seg.end)
        if seg.keyframes is not None:
            seg.keyframes.time = np.asarray(warp(seg.keyframes.time), dtype=float)
        seg.result = warp_result(seg.result, warp)
    if ir.root_plan is not None:
        ir.root_plan.time = np.asarray(warp(ir.root_plan.time), dtype=float)
