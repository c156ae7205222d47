"""The collision model and the clearance metric on a compiled example (mtlc.geometry.clearance),
checked independently with trimesh's closest-point query (not the collision library)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, site_positions
from mtlc.body.capsules import (
    ARM_LIMBS,
    body_capsules,
    capsule_segments,
    collision_capsules,
    limb_radius,
)
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.geometry.clearance import frame_clearance, goal_clearances
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

trimesh = pytest.importorskip("trimesh")

EXAMPLE = Path("examples/remove_access_panel.mtask")
HALF_BOX = 0.02  # m: a 4 cm cube


@pytest.fixture(scope="module", params=[("female", 5), ("male", 95)], ids=["F5", "M95"])
def panel_ir(request: pytest.FixtureRequest) -> MotionIR:
    program = run_frontend([EXAMPLE])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    sex, pct = request.param
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", sex, pct))
    return run_motion(timeline, DiagnosticSink())


def _stroke_frame(ir: MotionIR) -> int:
    """A frame in the middle of the first wrench stroke: the hand is at a bolt."""
    stroke = next(s for s in ir.segments if s.kind == "TO" and "stroke" in s.goal.params)
    return int(np.argmin(np.abs(ir.frames.time - 0.5 * (stroke.start + stroke.end))))


def _segments(ir: MotionIR):
    skel, f = ir.skeleton, ir.frames
    pose = forward(skel, f.q, f.root_position, f.root_rotation, with_axes=False)
    return skel, pose, collision_capsules(skel)


def _box_on(ir: MotionIR, part: str, frame: int) -> trimesh.Trimesh:
    """A cube centred on the middle of ``part``'s axis at ``frame``."""
    skel, pose, caps = _segments(ir)
    a, b, _ = capsule_segments(skel, pose, caps)
    j = [c.name for c in caps].index(part)
    box = trimesh.creation.box(extents=(2 * HALF_BOX,) * 3)
    box.apply_translation(0.5 * (a[frame, j] + b[frame, j]))
    return box


def test_capsules_are_sized_from_the_manikin() -> None:
    for sex, pct in (("female", 5), ("male", 95)):
        skel = build_manikin("gb10000_1988", sex, pct)
        pose = forward(skel, np.zeros(skel.n_dofs))
        caps = {c.name: c for c in collision_capsules(skel)}
        assert len(caps) == 16
        a, b, r = capsule_segments(skel, pose, tuple(caps.values()))
        names = list(caps)
        # one definition with the self-contact model: hands, forearms and thighs
        for limb in ARM_LIMBS:
            assert caps[limb.name].radius == pytest.approx(limb_radius(skel, limb))
        thigh = next(c for c in body_capsules(skel) if c.name == "right thigh")
        assert caps["right thigh"].radius == thigh.radius
        # the head's top is at the vertex, the soles on the floor, the hand ends at the fingertip
        head = names.index("head")
        vertex = site_positions(skel, pose, "vertex")
        assert b[head, 1] + r[head] == pytest.approx(vertex[1], abs=1e-9)
        foot = names.index("right foot")
        floor = site_positions(skel, pose, "r_heel")[1]
        assert a[foot, 1] - r[foot] == pytest.approx(floor, abs=1e-9)
        hand = names.index("right hand")
        tip = site_positions(skel, pose, "r_fingertip")
        assert np.linalg.norm(b[hand] - tip) == pytest.approx(r[hand], abs=1e-9)
    small = collision_capsules(build_manikin("gb10000_1988", "female", 5))
    big = collision_capsules(build_manikin("gb10000_1988", "male", 95))
    assert all(s.radius < b.radius for s, b in zip(small, big, strict=True))


def test_box_on_the_forearm_is_found_at_its_frame_and_goal(panel_ir: MotionIR) -> None:
    frames = panel_ir.frames
    k = _stroke_frame(panel_ir)
    box = _box_on(panel_ir, "right forearm", k)
    fc = frame_clearance(panel_ir, {"bracket": (box.vertices, box.faces)})
    j = fc.capsules.index("right forearm")
    radius = next(
        c.radius for c in collision_capsules(panel_ir.skeleton) if c.name.endswith("right forearm")
    )
    # the box's centre is on the axis: the axis touches it, the whole radius is in
    assert fc.clearance[k, j, 0] == pytest.approx(-radius, abs=1e-9)
    assert fc.clearance[k, j, 0] == np.nanmin(fc.clearance[:, j, 0])
    # the tool's capsule is measured only while the wrench is in the hand
    tool = fc.capsules.index("tool wrench_10mm")
    held = ~np.isnan(fc.clearance[:, tool, 0])
    assert held.any() and not held.all()
    # the goal whose stretch holds frame k reports the forearm at that depth, against the box
    t = frames.time[k]
    (goal,) = [g for g in goal_clearances(panel_ir, fc) if g.start <= t <= g.end]
    worst = goal.smallest
    assert worst is not None and worst.part == "right forearm" and worst.mesh == "bracket"
    assert worst.clearance == pytest.approx(-radius, abs=1e-9)
    # (the forearm rests in the box over the strokes: the first such frame is reported)
    first = np.flatnonzero(fc.clearance[:, j, 0] < -radius + 1e-9)[0]
    assert worst.time == pytest.approx(frames.time[first]) and worst.time <= t
    # a glove takes its thickness off the hand, not the forearm
    gloved = next(g for g in goal_clearances(panel_ir, fc, glove=0.004) if g.start <= t <= g.end)
    hand = next(p for p in goal.at_site if p.part == "right hand")
    hand_gloved = next(p for p in gloved.at_site if p.part == "right hand")
    assert hand_gloved.clearance == pytest.approx(hand.clearance - 0.004)
    assert gloved.smallest.clearance == pytest.approx(worst.clearance)


def test_clearance_agrees_with_trimesh_proximity(panel_ir: MotionIR) -> None:
    """Sample every capsule's axis every 20th frame and ask trimesh for the nearest surface
    point: the sampled distance less the radius is never below the metric, and above it by at
    most half the sample spacing (distance is 1-Lipschitz along the axis)."""
    frames = panel_ir.frames
    k = _stroke_frame(panel_ir)
    box = _box_on(panel_ir, "right forearm", k)
    fc = frame_clearance(panel_ir, {"bracket": (box.vertices, box.faces)}, horizon=None)
    skel, pose, caps = _segments(panel_ir)
    a, b, r = capsule_segments(skel, pose, caps)
    rows = np.union1d(np.arange(0, len(frames.time), 20), [k])
    samples = 41
    s = np.linspace(0.0, 1.0, samples)
    pts = a[rows, :, None, :] + s[None, None, :, None] * (b - a)[rows, :, None, :]
    _, dist, _ = trimesh.proximity.closest_point(box, pts.reshape(-1, 3))
    sampled = dist.reshape(len(rows), len(caps), samples).min(axis=2) - r
    ours = fc.clearance[rows, : len(caps), 0]
    half_spacing = 0.5 * np.linalg.norm(b - a, axis=-1)[rows] / (samples - 1)
    # (to a micrometre: coal's GJK tolerance, 1e-6 m; it answered 0.13 µm long on one pair)
    assert np.all(sampled >= ours - 1e-6)
    assert np.all(sampled - ours <= half_spacing + 1e-6)
    # and the penetration at frame k is seen by trimesh too
    assert (
        sampled[np.flatnonzero(rows == k)[0], [c.name for c in caps].index("right forearm")] < -0.02
    )


def test_no_meshes_means_nothing_near(panel_ir: MotionIR) -> None:
    fc = frame_clearance(panel_ir, {})
    assert fc.clearance.shape == (len(panel_ir.frames.time), len(fc.capsules), 0)
    goals = goal_clearances(panel_ir, fc)
    assert len(goals) == sum(s.kind == "TA" for s in panel_ir.segments)
    for goal in goals:
        word = "right" if goal.effector.startswith("r") else "left"
        assert {p.part for p in goal.path} >= {f"{word} hand", f"{word} forearm"}
        assert all(p.clearance == np.inf and p.mesh is None for p in goal.path + goal.at_site)
