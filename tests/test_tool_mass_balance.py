"""The held tool's mass in every centre of mass that judges balance (issue 8).

The smoothing pass's balance check, verify (whose figure the metrics and the preview read) and
the balance pass use ``carried_com``; the first two share one function, ``balance_margin`` over
the points that touch (``touching_support``, docs/metrics.md), so with the 1.2 kg torque wrench
in the hand they agree frame for frame, and differ from the bare body's margin by the tool's
hand-computed pull on the centre of mass.
"""

from __future__ import annotations

import numpy as np
import pytest

from mtlc.body import center_of_mass, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.metrics import balance_margin, compute_metrics, support_margin, touching_support
from mtlc.passes import run_motion
from mtlc.passes.tool import held_spans
from mtlc.preview.document import figures
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

TORQUE_KG = 1.2  # stdlib/tools.mtask: torque_wrench
TASK = """use stdlib.actions
use stdlib.tools

scene bay {
    site front at (0, 0, 60) cm
    site bolt at (20, 135, 112) cm normal (0, 0, -1)
}

task torque_bolt {
    scene bay
    tool torque_wrench
    walk_to(front)
    unscrew(right, bolt, turns: 1)
}
"""


@pytest.fixture(scope="module")
def torque_ir(tmp_path_factory: pytest.TempPathFactory) -> MotionIR:
    path = tmp_path_factory.mktemp("torque") / "t.mtask"
    path.write_text(TASK, encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "male", 50))
    return run_motion(timeline, DiagnosticSink())


def _held(ir: MotionIR, t: np.ndarray) -> np.ndarray:
    ((_, tool, start, end),) = held_spans(ir)
    assert tool["mass"] == pytest.approx(TORQUE_KG)
    return (t >= start - 1e-9) & (t <= end + 1e-9)


def test_smoothing_preview_and_metrics_margins_agree(torque_ir: MotionIR) -> None:
    frames, skel = torque_ir.frames, torque_ir.skeleton
    assert frames is not None and skel is not None
    t = frames.time
    pose = forward(skel, frames.q, frames.root_position, frames.root_rotation)
    smoothing = balance_margin(torque_ir, pose, t)  # what the smoothing pass checks
    preview = figures(torque_ir)["com_margin"]
    metrics = compute_metrics(torque_ir).support_margin
    held = _held(torque_ir, t)
    assert held.sum() > 0.3 * len(t)  # the wrench is in the hand for a good part of the task
    # one definition, every frame: walking, standing and the hand resting on the bolt alike
    np.testing.assert_allclose(preview, smoothing, atol=1e-12, equal_nan=True)
    np.testing.assert_allclose(metrics, smoothing, atol=1e-12, equal_nan=True)


def test_margin_moves_by_the_hand_computed_com_shift(torque_ir: MotionIR) -> None:
    frames, skel = torque_ir.frames, torque_ir.skeleton
    assert frames is not None and skel is not None
    t = frames.time
    pose = forward(skel, frames.q, frames.root_position, frames.root_rotation)
    pts, ok = touching_support(torque_ir, pose, t)
    bare_com = center_of_mass(skel, pose)
    bare = support_margin(pts, ok, bare_com[:, [0, 2]])
    # by hand: a 1.2 kg point at the middle of grip and tip, weighted against the body's mass
    big_m = skel.total_mass
    middle = 0.5 * (
        site_positions(skel, pose, "r_hand") + site_positions(skel, pose, "r_tool_torque_wrench")
    )
    held = _held(torque_ir, t)
    shift = np.where(held[:, None], TORQUE_KG / (big_m + TORQUE_KG) * (middle - bare_com), 0.0)
    by_hand = support_margin(pts, ok, (bare_com + shift)[:, [0, 2]])
    carried = balance_margin(torque_ir, pose, t)
    np.testing.assert_allclose(carried, by_hand, atol=1e-12, equal_nan=True)
    assert np.array_equal(carried[~held], bare[~held], equal_nan=True)  # nothing outside
    moved = np.abs(carried - bare)[held]
    ground_shift = np.hypot(shift[held, 0], shift[held, 2])
    assert np.all(moved <= ground_shift + 1e-12)  # a margin moves at most as far as the CoM
    assert moved.max() > 5e-3  # 1.2 kg held 40 cm out: up to 9.6 mm here
