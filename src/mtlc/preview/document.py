"""What the preview page shows, as one JSON-ready dict: the IR, per-frame figures, timeline blocks.

The page recomputes the pose from the IR itself (forward kinematics in JavaScript), so the dict
carries the IR's versioned JSON unchanged; next to it go the figures the page cannot cheaply
compute (support margin, penetration, contact error, RULA) and the task › action › element
blocks of the timeline with the source lines they came from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body import forward, site_positions
from mtlc.body.kinematics import Pose
from mtlc.diagnostics.render import source_lines
from mtlc.ergonomics.rula import task_scores, worst_grand
from mtlc.ergonomics.view import DEFAULT_HALF_ANGLE_DEG
from mtlc.ir.model import MotionIR, Segment
from mtlc.ir.serialize import to_dict
from mtlc.metrics import foot_stance, hand_contacts, penetration, support, support_margin
from mtlc.passes.tool import carried_com

FloatArray = NDArray[np.float64]
PREVIEW_FORMAT_VERSION = 1
LEVELS = ("task", "action", "element")


@dataclass(frozen=True)
class Block:
    """One bar of the timeline: a task, an action or an element, with where it was written."""

    level: int  # 0 task, 1 action, 2 element
    label: str
    path: str
    start: float
    end: float
    lane: int
    origin: dict[str, Any]  # the task's line that asked for it
    source: dict[str, Any]  # the statement that defines it (often in the stdlib)


# -- per-frame figures -------------------------------------------------------------------------


def contact_error_per_frame(ir: MotionIR, pose: Pose, time: FloatArray) -> FloatArray:
    """(N,) worst hand-to-site distance (m) while a hand rests on a site it reached, else NaN.

    Only sites the solver reached count (as in ``mtlc.metrics``). A hand rests from the end of its TO segment until the next segment on its arm's track or on
    the root's starts (the body moving carries the hand away): that is where the contact error of
    ``docs/metrics.md`` lives.
    """
    out = np.full(len(time), np.nan)
    root_starts = sorted(s.start for s in ir.on_track("root"))
    for track in ("r_arm", "l_arm"):
        segs = sorted(ir.on_track(track), key=lambda s: s.start)
        for k, seg in enumerate(segs):
            if seg.kind != "TO" or seg.goal.position is None or not _reached(seg.result):
                continue
            next_arm = segs[k + 1].start if k + 1 < len(segs) else math.inf
            next_root = next((t for t in root_starts if t >= seg.end - 1e-9), math.inf)
            until = min(next_arm, next_root)
            resting = (time >= seg.end - 1e-9) & (time <= until + 1e-9)
            # and the first frame at or after the TO's end, where the metrics measure (a
            # wrench's stroke is followed at once by the next: no frame lies between)
            resting[min(int(np.searchsorted(time, seg.end - 1e-9)), len(time) - 1)] = True
            if not resting.any():
                continue
            hand = site_positions(ir.skeleton, pose, seg.goal.effector)[resting]
            err = np.linalg.norm(hand - np.asarray(seg.goal.position, dtype=float), axis=-1)
            out[resting] = np.fmax(out[resting], err)
    return out


def _reached(result: Mapping[str, Any]) -> bool:
    """The solver's verdict; an unreachable site is reported as a diagnostic, not an error."""
    return all(bool(result[key]) for key in ("reachable", "success", "reached") if key in result)


def figures(ir: MotionIR) -> dict[str, FloatArray]:
    """Per-frame contact error, centre-of-mass margin, penetration and RULA (worst so far)."""
    frames, skel = ir.frames, ir.skeleton
    if frames is None or skel is None:
        raise ValueError("the IR has no frames: run the motion passes first")
    t = np.asarray(frames.time, dtype=float)
    pose = forward(skel, frames.q, frames.root_position, frames.root_rotation)
    stance = foot_stance(ir, t)
    pts, ok = support(skel, pose, stance, ir.ground, hand_contacts(ir, t, pose))  # as metrics
    margin = support_margin(pts, ok, carried_com(ir, pose, t)[:, [0, 2]])  # tools held count
    rula = worst_grand(task_scores(ir, pose, frames.q, t, stance.all(axis=1)))
    rula = rula.astype(float)
    return {
        "contact_error": contact_error_per_frame(ir, pose, t),
        "com_margin": margin,
        "penetration": penetration(skel, pose, ir.ground),
        "rula": rula,
        "rula_worst_so_far": np.maximum.accumulate(rula),
    }


# -- timeline blocks ---------------------------------------------------------------------------


def _ref(ref: Any, sources: Mapping[str, str]) -> dict[str, Any]:
    """A source reference with the text of its line, for the page's hover."""
    lines = source_lines(sources.get(ref.file, ""))  # not splitlines(): it breaks at \f too
    text = lines[ref.line - 1].strip() if 0 < ref.line <= len(lines) else ""
    return {"file": ref.file, "line": ref.line, "column": ref.column, "text": text}


def _lanes(spans: Sequence[tuple[float, float]]) -> list[int]:
    """Greedy lane per span (sorted by start) so that overlapping spans never share a lane."""
    ends: list[float] = []
    lanes: list[int] = []
    for start, end in spans:
        lane = next((i for i, e in enumerate(ends) if e <= start + 1e-9), len(ends))
        if lane == len(ends):
            ends.append(end)
        else:
            ends[lane] = end
        lanes.append(lane)
    return lanes


def _action_runs(segs: Sequence[Segment]) -> list[list[Segment]]:
    """Segments grouped into action instances.

    A run continues while the action name and the task line stay the same and the run's first
    element does not start again (a loop calling the same action restarts its elements).
    """
    runs: list[list[Segment]] = []
    for seg in segs:
        run = runs[-1] if runs else None
        same = (
            run is not None
            and seg.provenance.path[1:2] == run[0].provenance.path[1:2]
            and seg.provenance.origin == run[0].provenance.origin
            and not (
                seg.provenance.path[2:3] == run[0].provenance.path[2:3]
                and seg.track == run[0].track
            )
        )
        if same and run is not None:
            run.append(seg)
        else:
            runs.append([seg])
    return runs


def blocks(ir: MotionIR, sources: Mapping[str, str]) -> list[Block]:
    """The task, its action instances and its elements, each with its source lines."""
    segs = sorted(ir.segments, key=lambda s: (s.start, s.end, s.track))
    if not segs:
        return []
    out: list[Block] = []
    first = segs[0].provenance
    task_end = max(s.end for s in segs)
    out.append(
        Block(0, first.path[0], first.path[0], 0.0, task_end, 0,
              _ref(first.origin, sources), _ref(first.origin, sources))
    )  # fmt: skip
    runs = [r for r in _action_runs(segs) if len(r[0].provenance.path) > 1]
    spans = [(min(s.start for s in r), max(s.end for s in r)) for r in runs]
    for run, (start, end), lane in zip(runs, spans, _lanes(spans), strict=True):
        head = run[0].provenance
        path = " > ".join(head.path[:2])
        out.append(
            Block(1, head.path[1], path, start, end, lane,
                  _ref(head.origin, sources), _ref(head.origin, sources))
        )  # fmt: skip
    elems = [s for s in segs if s.end > s.start]
    for seg, lane in zip(elems, _lanes([(s.start, s.end) for s in elems]), strict=True):
        prov = seg.provenance
        site = f" {seg.goal.site}" if seg.goal.site else ""
        out.append(
            Block(2, f"{prov.path[-1]} ({seg.kind}{site})", " > ".join(prov.path), seg.start,
                  seg.end, lane, _ref(prov.origin, sources), _ref(prov.span, sources))
        )  # fmt: skip
    return out


# -- the document ------------------------------------------------------------------------------


def _plain(values: FloatArray, decimals: int = 6) -> list[float | None]:
    """Rounded floats for JSON; NaN becomes null (JSON has no NaN)."""
    return [None if not math.isfinite(v) else round(float(v), decimals) + 0.0 for v in values]


def preview_document(
    ir: MotionIR,
    sources: Mapping[str, str],
    site_spans: Mapping[str, dict[str, Any]] | None = None,
    view_cone_half_angle: float = DEFAULT_HALF_ANGLE_DEG,
) -> dict[str, Any]:
    """The page's data: the IR's JSON, per-frame figures, timeline blocks and the view cone's
    half-angle (degrees, docs/visibility.md); deterministic."""
    figs = figures(ir)
    return {
        "format": "mtlc-preview",
        "version": PREVIEW_FORMAT_VERSION,
        "ir": to_dict(ir),
        "figures": {name: _plain(values) for name, values in figs.items()},
        "blocks": [
            {
                "level": b.level,
                "kind": LEVELS[b.level],
                "label": b.label,
                "path": b.path,
                "start": round(b.start, 6),
                "end": round(b.end, 6),
                "lane": b.lane,
                "origin": b.origin,
                "source": b.source,
            }
            for b in blocks(ir, sources)
        ],
        "site_sources": dict(site_spans or {}),
        "view_cone": {"half_angle_deg": float(view_cone_half_angle)},
    }
