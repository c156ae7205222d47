"""Issue 19: a part moved in both hands keeps its length on every frame.

The pace pass plans the part's path (its centre, its axis, the grip's length) and derives both
hands' targets from it; both arms follow it point after point. tests/data/two_hands holds two
procedures written for it: a cover lifted by its front edge from waist height to above the head
(t01), a 6 kg box taken off the floor from a squat and put on a bench at waist height (t02).
Measured on the sampled frames: on every two-handed move made while both hands hold the part,
the hands' distance stays within 5 mm of what it was when they closed on it, and verify finds
no part squeezed or stretched (MT0511).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.ir.model import MotionIR
from mtlc.lint.manikins import all_manikins
from mtlc.passes.carry import carries, part_path
from mtlc.semantics.timeline import ManikinSpec

ROOT = Path(__file__).resolve().parents[2]
PROCEDURES = sorted((ROOT / "tests" / "data" / "two_hands").glob("*.mtask"))
MANIKINS = [m for m in all_manikins() if (m.sex, m.percentile) in
            (("female", 5), ("male", 50), ("male", 95))]  # fmt: skip
KEPT = 5e-3  # m: the hands' distance stays this close to the grip's


def compile_for(path: Path, manikin: ManikinSpec) -> tuple[MotionIR, DiagnosticSink]:
    return compile_on(path, manikin)


def hands_apart(ir: MotionIR) -> np.ndarray:
    frames = ir.frames
    assert frames is not None
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation,
                   with_axes=False)  # fmt: skip
    hands = np.asarray(site_positions(ir.skeleton, pose, ["r_hand", "l_hand"]))
    return np.linalg.norm(hands[:, 0] - hands[:, 1], axis=1)


@pytest.mark.parametrize("manikin", MANIKINS, ids=lambda m: f"{m.sex}-p{m.percentile}")
@pytest.mark.parametrize("path", PROCEDURES, ids=lambda p: p.stem)
def test_a_part_moved_in_both_hands_keeps_its_length(path: Path, manikin: ManikinSpec) -> None:
    ir, sink = compile_for(path, manikin)
    frames = ir.frames
    assert frames is not None
    apart = hands_apart(ir)
    moves = 0
    for carry in carries(ir):
        grip = int(np.searchsorted(frames.time, carry.start - 1e-9))
        for seg in ir.segments:
            if (
                seg.track == "r_arm"
                and seg.kind in ("TA", "TO")
                and seg.goal.params.get("two_handed")
                and carry.start - 1e-9 <= seg.start < carry.end
            ):
                inside = (frames.time >= seg.start - 1e-9) & (frames.time <= seg.end + 1e-9)
                change = float(np.abs(apart[inside] - apart[grip]).max())
                assert change <= KEPT, (seg.kind, seg.goal.site, round(change * 1000, 1))
                moves += 1
    assert moves >= 2  # the TA and the TO of the move at least: the test measured something
    assert [d.message for d in sink.items if d.code == "MT0511"] == []


def test_the_part_path_keeps_the_grip_length_and_turns_the_axis() -> None:
    t = np.linspace(0.0, 1.0, 9)[:, None]
    # two hands each on its own path: 20 cm apart across x at the start, 30 cm apart along z
    # at the end, their mid-point rising by 80 cm
    mid = np.hstack([np.zeros_like(t), 0.95 + 0.8 * t, np.zeros_like(t)])
    spread = np.where(t < 1.0, 0.10 + 0.3 * np.sin(np.pi * t), 0.15)
    axis_start, axis_end = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    axis = np.where(t < 0.5, axis_start, axis_end)
    hands = np.stack([mid + spread * axis, mid - spread * axis], axis=1)
    hands[0] = [[0.1, 0.95, 0.0], [-0.1, 0.95, 0.0]]
    ends = part_path(hands, 0.2)
    apart = np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1)
    assert np.allclose(apart, 0.2)  # the grip's length on every point, however the hands went
    assert np.allclose(ends.mean(axis=1), mid)  # the centre is the hands' mid-point
    direction = (ends[:, 0] - ends[:, 1]) / 0.2
    assert np.allclose(direction[0], axis_start) and np.allclose(direction[-1], axis_end)
    turned = np.degrees(np.arccos(np.clip(direction @ axis_start, -1.0, 1.0)))
    assert np.all(np.diff(turned) >= -1e-9)  # the axis turns one way, in one plane
    assert np.allclose(direction[:, 1], 0.0)
