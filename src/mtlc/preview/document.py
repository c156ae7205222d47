"""What the preview page shows, as one JSON-ready dict: the IR, per-frame figures, timeline blocks.

The page recomputes the pose from the IR itself (forward kinematics in JavaScript), so the dict
carries the IR's versioned JSON unchanged; next to it go the figures the page cannot cheaply
compute (support margin, penetration and contact error, as the verify pass measured them; RULA;
with equipment geometry, the body's clearance to it) and the task › action › element blocks of
the timeline with the source lines they came from, and the scene's models as triangles (the IR
names a model's file, the page is self-contained: it draws what the compile read).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body import forward
from mtlc.diagnostics.render import source_lines
from mtlc.ergonomics.rula import task_scores, worst_grand
from mtlc.ergonomics.view import DEFAULT_HALF_ANGLE_DEG
from mtlc.ir.model import MotionIR, Segment
from mtlc.ir.serialize import to_dict
from mtlc.metrics import foot_stance

FloatArray = NDArray[np.float64]
PREVIEW_FORMAT_VERSION = 1
MAX_DRAWN_TRIANGLES = 200_000  # over this, the page draws a model's bounding box (a big page)
DRAWN_DECIMALS = 4  # m: the vertices to 0.1 mm
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


def figures(ir: MotionIR) -> dict[str, FloatArray]:
    """Per-frame contact error, centre-of-mass margin, penetration and RULA (worst so far).

    The first three are what the verify pass measured on the output frames
    (``MotionIR.verification``, docs/metrics.md), so the page shows the numbers `compile
    --metrics`, `lint` and `report` give: the contact error of the hands resting on sites they
    reached (NaN elsewhere), the margin of the centre of mass (with what the hands hold) over
    the support of the points that touch, and the depth of the lowest body point (fingertips and
    tool tips included). RULA is scored here."""
    frames, skel, v = ir.frames, ir.skeleton, ir.verification
    if frames is None or skel is None:
        raise ValueError("the IR has no frames: run the motion passes first")
    if v is None:
        raise ValueError("the motion is not verified: run the verify pass last")
    t = np.asarray(frames.time, dtype=float)
    pose = forward(skel, frames.q, frames.root_position, frames.root_rotation)
    stance = foot_stance(ir, t)
    rula = worst_grand(task_scores(ir, pose, frames.q, t, stance.all(axis=1)))
    rula = rula.astype(float)
    return {
        "contact_error": v.contact_error,
        "com_margin": v.support_margin,
        "penetration": v.penetration_frames,
        "rula": rula,
        "rula_worst_so_far": np.maximum.accumulate(rula),
    }


def clearance_figures(ir: MotionIR) -> dict[str, Any] | None:
    """Per frame, the smallest clearance (m) of any body capsule, held tool or held part to
    any model, and which pair (indices into ``parts`` and ``meshes``); None without geometry.

    Read from what verify measured and judged (``Verification.equipment_clearance``,
    docs/collision.md), not measured again: a contact verify excuses (a hand or its tool at
    its goal's site, a hand on the part it holds) is no clash here either, and a held part in
    the rest of the equipment is a pair of its own (``held part model/node``, minus its
    depth), so the page paints red what `compile` reports (MT0515)."""
    v = ir.verification
    fc = v.equipment_clearance if v is not None else None
    if fc is None or not fc.meshes:
        return None
    values = np.where(np.isnan(fc.clearance), np.inf, fc.clearance)
    if fc.excused.shape == values.shape:
        values = np.where(fc.excused, np.inf, values)
    parts = list(fc.capsules)
    if fc.held:
        depth = np.nan_to_num(fc.held_depth, nan=0.0)
        values = np.concatenate([values, np.where(depth > 0.0, -depth, np.inf)], axis=1)
        parts += [f"held part {column}" for column in fc.held]
    n, c, m = values.shape
    flat = values.reshape(n, c * m)
    k = np.argmin(flat, axis=1)
    return {
        "values": flat[np.arange(n), k],
        "parts": parts,
        "meshes": list(fc.meshes),
        "part": (k // m).tolist(),
        "mesh": (k % m).tolist(),
    }


def _rounded(values: NDArray[Any]) -> list[float]:
    return [round(float(x), DRAWN_DECIMALS) + 0.0 for x in np.ravel(values)]


def _held_drawn(model: Any, part: Any) -> dict[str, Any]:
    """A held part for the page: its own vertices and triangles (as the model puts it) and
    its placement on every output frame (the top three rows of the 4 x 4, flat), so that the
    page moves it with the hand (``verification.equipment.held`` says who holds it when)."""
    faces = model.faces[part.faces]
    used, local = np.unique(faces, return_inverse=True)
    return {
        "name": part.column,
        "drawn": "mesh",
        "held": True,
        "triangles": len(faces),
        "positions": _rounded(model.vertices[used]),
        "indices": [int(i) for i in local.ravel()],
        "placement": [[round(float(x), 6) + 0.0 for x in m[:3].ravel()] for m in part.placement],
    }


def drawn_models(ir: MotionIR) -> list[dict[str, Any]]:
    """The scene's models for the page: vertices (flat, m, rounded) and triangles (flat
    indices); past MAX_DRAWN_TRIANGLES in all, a model is drawn as its bounding box. A part a
    hand holds is drawn on its own after its model (``_held_drawn``), and not in it."""
    from mtlc.geometry.solids import box

    held = ir.verification.held_parts if ir.verification is not None else []
    out, budget = [], MAX_DRAWN_TRIANGLES
    for model in ir.geometry:
        parts = [p for p in held if p.model == model.name]
        taken = np.zeros(len(model.faces), dtype=bool)
        for part in parts:
            taken[part.faces] = True
        vertices, faces, drawn = model.vertices, model.faces[~taken], "mesh"
        if len(faces) > budget and len(vertices):
            lo, hi = vertices.min(axis=0), vertices.max(axis=0)
            vertices, faces = box(tuple(hi - lo))  # type: ignore[arg-type]
            vertices, drawn, parts = vertices + (lo + hi) / 2, "box", []
        budget -= len(faces)
        out.append(
            {
                "name": model.name,
                "drawn": drawn,
                "triangles": model.triangles - int(taken.sum()),  # less the held parts'
                "positions": _rounded(vertices),
                "indices": [int(i) for i in faces.ravel()],
            }
        )
        out += [_held_drawn(model, part) for part in parts]
    return out


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
    clear = clearance_figures(ir)
    if clear is not None:
        figs["clearance"] = clear.pop("values")
    doc = {
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
    if ir.geometry:  # scenes without models keep their documents as they were
        doc["models"] = drawn_models(ir)
        doc["clearance"] = clear
    return doc
