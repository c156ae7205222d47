"""The trunk a reach leaned comes back toward upright over the free time (passes/upright.py).

After a reach to 35 cm (the trunk flexed 72 deg, male P50) the body went on bent double to the
inspection of a gauge at head height: nothing but a user-written `stand()` straightened it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import parse_selection
from mtlc.passes import run_motion
from mtlc.semantics import schedule

DATA = Path(__file__).parents[1] / "data" / "upright"
TRUNK_FLEX = ("lumbar_flex", "thorax_flex")
UPRIGHT_DEG = 10.0  # the trunk this close to its rest pose counts as upright


def _compile(path: Path, manikin: str) -> MotionIR:
    program = run_frontend([path])
    assert not program.sink.has_errors
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, parse_selection(manikin)[0])
    return run_motion(timeline, DiagnosticSink())


def _trunk_flexion(ir: MotionIR) -> np.ndarray:
    """Lumbar plus thorax flexion (deg) per frame, from the rest pose."""
    skel = ir.skeleton
    assert skel is not None and ir.frames is not None
    cols = [skel.dof_index(n) for n in TRUNK_FLEX]
    rest = np.asarray(skel.q_comfort, dtype=float)[cols].sum()
    return np.degrees(ir.frames.q[:, cols].sum(axis=1) - rest)


@pytest.mark.parametrize(
    "manikin", ["gb10000_1988:female:5", "gb10000_1988:male:50", "gb10000_1988:male:95"]
)
def test_the_trunk_is_upright_at_the_inspection_after_a_floor_reach(manikin: str) -> None:
    ir = _compile(DATA / "u01_floor_then_overhead.mtask", manikin)
    flexion = _trunk_flexion(ir)
    t = ir.frames.time  # type: ignore[union-attr]
    (press,) = [s for s in ir.segments if s.kind == "TO" and s.track == "r_arm"][-1:]
    assert flexion[np.argmin(np.abs(t - press.end))] > 30.0  # the reach leaned it
    (inspection,) = [s for s in ir.segments if s.kind == "hold" and s.track == "root"]
    # the last two of the inspection's three seconds: the way up is over by then
    looking = (t >= inspection.end - 2.0) & (t <= inspection.end)
    assert np.abs(flexion[looking]).max() < UPRIGHT_DEG, np.abs(flexion[looking]).max()
    # on a ramp, not a snap: no more than 12 deg in one output frame
    assert np.abs(np.diff(flexion)).max() < 12.0
    (rest,) = [s for s in ir.segments if s.kind == "rest" and s.track == "spine"]
    assert press.end - 1e-6 <= rest.start <= inspection.end


def test_a_hand_on_its_site_at_arms_length_keeps_the_trunk(tmp_path: Path) -> None:
    """A hand still holding a low handle pins the shoulder: the trunk stays as far down as it
    needs for the hand to stay on the handle (no `rest` segment, the hold keeps its site)."""
    source = (DATA / "u01_floor_then_overhead.mtask").read_text(encoding="utf-8")
    path = tmp_path / "held.mtask"
    path.write_text(source.replace("press(right, floor_plug)", "pick(right, floor_plug)"))
    ir = _compile(path, "gb10000_1988:male:50")
    assert not [s for s in ir.segments if s.kind == "rest" and s.track == "spine"]
    assert _trunk_flexion(ir)[-1] > 30.0
