"""The tool pass's shortcuts leave its keyframes bit for bit as the full solve makes them:
the key and row solves remembered across a fastener's series (``tool.Solves``), and the
still-trunk solve skipped where a key is beyond the arm's reach (``tool._beyond_girdle``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.passes import tool as tool_pass
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

# the left hand turns one bolt twice, the right hand somewhere else each time (the second
# series asks the first one's questions with another right arm), then a bolt on the floor
# 3 m ahead: the torso leans toward it and no still trunk lets the arm reach it
TASK = """use stdlib.actions
use stdlib.tools
use stdlib.elements

scene bay {
    site front at (0, 0, 60) cm
    site bolt at (20, 135, 112) cm normal (0, 0, -1)
    site far at (0, 300, 60) cm normal (0, 1, 0)
    site shelf_a at (-35, 100, 80) cm
    site shelf_b at (-35, 115, 85) cm
}

task t {
    scene bay
    tool wrench_10mm
    walk_to(front)
    for x in [shelf_a, shelf_b] {
        move(right, x)
        unscrew(left, bolt, turns: 1)
    }
    unscrew(left, far, turns: 1)
}
"""


def _run(tmp: Path) -> MotionIR:
    path = tmp / "t.mtask"
    path.write_text(TASK, encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    man = ManikinSpec("gb10000_1988", "female", 5)
    return run_motion(schedule.for_manikin(timeline, man), DiagnosticSink(), until="tool")


def _assert_same(a: MotionIR, b: MotionIR) -> None:
    assert len(a.segments) == len(b.segments)
    strokes = 0
    for x, y in zip(a.segments, b.segments, strict=True):
        assert (x.keyframes is None) == (y.keyframes is None)
        if x.keyframes is None:
            continue
        strokes += "stroke" in x.goal.params
        assert x.keyframes.dofs == y.keyframes.dofs
        assert np.array_equal(x.keyframes.time, y.keyframes.time)
        assert np.array_equal(x.keyframes.q, y.keyframes.q)
    assert strokes >= 3


def _spy(monkeypatch: pytest.MonkeyPatch, name: str, record: list[Any]) -> None:
    real = getattr(tool_pass, name)

    def spy(*args: Any, **kw: Any) -> Any:
        out = real(*args, **kw)
        record.append(out)
        return out

    monkeypatch.setattr(tool_pass, name, spy)


def test_remembered_solves_equal_fresh_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rows: list[Any] = []
    _spy(monkeypatch, "solve_rows", rows)
    remembered = _run(tmp_path)
    asked = sum(len(r) for r in rows)
    rows.clear()
    monkeypatch.setattr(tool_pass, "REMEMBER_SOLVES", False)
    fresh = _run(tmp_path)
    assert sum(len(r) for r in rows) > asked * 1.2  # the second series was looked up
    _assert_same(remembered, fresh)


def test_no_still_trunk_solve_beyond_reach(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    found: list[Any] = []
    _spy(monkeypatch, "_beyond_girdle", found)
    skipped = _run(tmp_path)
    assert any(found)  # the far bolt's still-trunk solve was skipped
    monkeypatch.setattr(tool_pass, "_beyond_girdle", lambda *a: False)
    solved = _run(tmp_path)
    _assert_same(skipped, solved)


def test_remembered_curves_and_shares_pace_a_stroke_as_fresh_ones() -> None:
    # a series' strokes share their phases' curves and windows (``_stroke_shares``): the
    # paced keyframes of a stroke at another start equal those built afresh, to the bit
    frac, _, lift = tool_pass.stroke_plan(0.3, 1.0, False, 0.12)
    rng = np.random.default_rng(5)
    q = np.cumsum(rng.normal(0.0, 0.05, (len(frac), 6)), axis=0)
    speed = np.full(6, 3.0)
    cache: dict[str, Any] = {}
    curves: dict[Any, Any] = {}
    for start in (0.0, 1.37, 2.911):
        windows = tool_pass._stroke_shares(cache, frac, q, True, speed)
        assert windows == tool_pass.phase_shares(frac, q, True, speed)
        got = tool_pass.paced_stroke(frac, q, start, start + 0.8, True, windows, curves)
        want = tool_pass.paced_stroke(frac, q, start, start + 0.8, True, windows)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    # the seat is a line (two keys); the swing and the return are curves
    assert lift.max() > 0 and len(curves) == 2 and len(cache["passes.tool.shares"]) == 1
