"""The IR's versioned JSON form (docs/ir.md): complete enough to recompute every frame.

It carries the skeleton (joint tree, offsets, dof axes in order, limits, masses, centres of
mass), the scene, the goals, every segment with its keyframes and provenance, and the sampled
frames. Numbers are rounded (lengths to 0.01 mm, angles to 1e-5 rad, times to 1 µs) so the same
input gives the same bytes and the last printed digit is not floating-point noise.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from mtlc.ir.model import (
    IR_FORMAT_VERSION,
    FloatArray,
    Keyframes,
    MotionIR,
    Segment,
    SourceRef,
    Verification,
)
from mtlc.jsontext import escape_surrogates

DECIMALS = 5  # lengths to 0.01 mm, angles to 1e-5 rad (0.0006°), masses to 0.01 g
TIME_DECIMALS = 6  # times to 1 µs, as JackScript writes them: frame times stay on their frames
# Keys whose numbers are times (s) or rates (1/s); every other number gets DECIMALS.
TIME_KEYS = frozenset({"time", "t_start", "t_end", "fps", "closest_time", "static_margin_time"})


# |x| below which x * 10**decimals is an integer-exact double (< 2**53 for 6 decimals) with
# room to spare: larger numbers are rounded one by one
EXACT_LIMIT = 1e8


def round_array(x: FloatArray, decimals: int) -> FloatArray:
    """``round(float(v), decimals)`` of every element, -0.0 made 0.0, computed at once.

    Python's ``round`` picks the decimal nearest to the exact binary value and returns the
    double nearest to it; ``k / 10**decimals`` with an integer-exact ``k`` is that double too
    (one correctly rounded division). ``rint(x * 10**decimals)`` picks the same ``k`` unless the
    product lies within its rounding error of a half, or the number is large: those few
    elements (and NaN and infinities) are rounded by ``round`` itself.
    """
    scale = 10.0**decimals
    y = x * scale
    k = np.rint(y)
    with np.errstate(invalid="ignore"):
        odd = ~(np.abs(x) < EXACT_LIMIT) | (
            np.abs(np.abs(y - k) - 0.5) <= 4 * np.spacing(np.abs(y))
        )
    out = k / scale + 0.0  # + 0.0: -0.0 becomes 0.0
    for i in np.flatnonzero(odd):
        r = round(float(x.flat[i]), decimals)
        out.flat[i] = 0.0 if r == 0 else r
    return out


def _num(v: Any, decimals: int = DECIMALS) -> Any:
    """JSON-able copy of ``v`` with every float rounded, and -0.0 written as 0.0.

    The rounding is far coarser than the last bits a different BLAS build changes (about 1e-8
    rad on the examples) and far finer than a reader needs to recompute frames (docs/ir.md).
    A float array is rounded at once (``round_array``): the frames are most of the numbers.
    """
    if isinstance(v, np.ndarray):
        if v.dtype.kind == "f":
            return round_array(v.astype(np.float64), decimals).tolist()
        return _num(v.tolist(), decimals)
    if isinstance(v, float | np.floating):
        r = round(float(v), decimals)
        return 0.0 if r == 0 else r
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, list | tuple):
        return [_num(x, decimals) for x in v]
    if isinstance(v, dict):
        return {k: _num(x, TIME_DECIMALS if k in TIME_KEYS else decimals) for k, x in v.items()}
    return v


def _ref(r: SourceRef) -> dict[str, Any]:
    return {"file": r.file, "line": r.line, "column": r.column}


def _keyframes(kf: Keyframes | None) -> dict[str, Any] | None:
    if kf is None:
        return None
    out: dict[str, Any] = {"time": kf.time, "dofs": list(kf.dofs), "q": kf.q}
    if kf.root_position is not None:
        out["root_position"] = kf.root_position
    if kf.root_rotation is not None:
        out["root_rotation"] = kf.root_rotation
    return out


def _segment(s: Segment) -> dict[str, Any]:
    g = s.goal
    return {
        "track": s.track,
        "kind": s.kind,
        "t_start": s.start,
        "t_end": s.end,
        "goal": {
            "effector": g.effector,
            "site": g.site,
            "position": g.position,
            "orientation": g.orientation,
            "approach": g.approach,
            **({"params": g.params} if g.params else {}),
        },
        "path": " > ".join(s.provenance.path),
        "source": _ref(s.provenance.span),
        "origin": _ref(s.provenance.origin),
        "keyframes": _keyframes(s.keyframes),
        "result": s.result,
    }


def _verification(v: Verification | None) -> dict[str, Any] | None:
    """What verify measured, per goal, grip and point class (docs/ir.md): the figures, not the
    per-frame series (they are recomputed from the frames by the same pass)."""
    if v is None:
        return None
    finite = lambda x: None if x is None or not math.isfinite(x) else x  # noqa: E731
    return {
        "contacts": v.contacts,
        "grips": v.grips,
        "penetration": v.penetration,
        "limits": {**v.limits, "time": finite(v.limits.get("time"))} if v.limits else {},
        "self_intersection": v.self_intersection,
        "static_margin": finite(v.static_margin),
        "static_margin_time": finite(v.static_margin_time),
        "findings": v.findings,
    } | ({"equipment": v.equipment} if v.equipment else {})


def to_dict(ir: MotionIR) -> dict[str, Any]:
    skel = ir.skeleton
    manikin = {**ir.manikin, **(skel.to_dict() if skel is not None else {})}
    goals = [
        {
            "effector": s.goal.effector,
            "site": s.goal.site,
            "phase": s.kind,
            "t_start": s.start,
            "t_end": s.end,
            "position": s.goal.position,
            "orientation": s.goal.orientation,
            "source": {**_ref(s.provenance.origin), "path": " > ".join(s.provenance.path)},
        }
        for s in ir.segments
        if s.kind in ("TA", "TO")
    ]
    frames = None
    if ir.frames is not None:
        f = ir.frames
        frames = {
            "fps": f.fps,
            "time": f.time,
            "root_position": f.root_position,
            "root_rotation": f.root_rotation,
            "dof_names": [d.name for d in skel.dofs] if skel is not None else [],
            "q": f.q,
        }
    doc = {
        "format": "mtlc-ir",
        "version": IR_FORMAT_VERSION,
        "units": {"length": "m", "angle": "rad", "time": "s", "mass": "kg"},
        "source": {"file": ir.file, "task": ir.task, "title": ir.title},
        "manikin": manikin,
        "scene": {"ground": ir.ground, "sites": ir.sites}
        | ({"models": ir.models} if ir.models else {}),
        "goals": goals,
        "segments": [_segment(s) for s in ir.segments],
        "frames": frames,
        "verification": _verification(ir.verification),
    }
    return _num(doc)


def to_json(ir: MotionIR) -> str:
    return (
        escape_surrogates(
            json.dumps(to_dict(ir), ensure_ascii=False, separators=(",", ":"), allow_nan=False)
        )
        + "\n"
    )
