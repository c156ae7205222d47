"""A hand that holds a site stays on it on the output frames, or a diagnostic says it cannot.

Issue 18: two parallel reaches of different lengths that both need the trunk pulled the first
hand 250-380 mm off its site; on the fuel filter the left hand's trunk-assisted reach dragged
the right hand 75-121 mm off the bowl it holds; a lever held behind the body was left 157 mm
and more behind by a kneel. All of it silently. Measured here on the sampled frames (the ones
a user receives), by forward kinematics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion
from mtlc.passes.hold import hold_spans

ROOT = Path(__file__).resolve().parents[2]
HEAD = "use stdlib.actions\nuse stdlib.elements\n\n"

PARALLEL = (
    HEAD
    + """scene bench {
    ground 0 cm
    site low_left at (45, 45, 55) cm normal (0, 1, 0)
    site far_right at (-40, 70, 75) cm normal (0, 1, 0)
}

task par_trunk "Two parallel trunk reaches of different lengths" {
    manikin gb10000_1988 male p50
    scene bench
    parallel {
        reach(left, low_left, A)
        reach(right, far_right, C)
    }
    parallel {
        grasp(left)
        grasp(right)
    }
    hold(1 s)
}
"""
)

KNEEL = (
    HEAD
    + """scene bay {
    ground 0 cm
    site lever at (-20, 90, -30) cm
}

task behind_kneel "Reach behind, then kneel" {
    manikin gb10000_1988 male p50
    scene bay
    reach(right, lever)
    grasp(right)
    kneel(2)
    hold(1 s)
}
"""
)


def compile_text(tmp: Path, text: str, sex: str, pct: int) -> tuple[MotionIR, DiagnosticSink]:
    path = tmp / "case.mtask"
    path.write_text(text)
    return compile_file(path, sex, pct)


def compile_file(path: Path, sex: str, pct: int) -> tuple[MotionIR, DiagnosticSink]:
    return compile_on(path, (sex, pct))


def hold_misses(ir: MotionIR) -> list[tuple[int, str, float]]:
    """(task line, site, worst distance in m) of every hold over the sampled frames: the hand's
    distance to its site from the frame at its contact's end until the hold ends."""
    frames = ir.frames
    assert frames is not None
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    out = []
    for seg, end in hold_spans(ir):
        if float(seg.result.get("distance", 1.0)) > 1e-3:
            continue  # a reach already reported short holds where it stopped
        rows = (frames.time >= seg.end - 1e-6) & (frames.time < end - 1e-9)
        if not rows.any():
            continue
        at = site_positions(ir.skeleton, pose, seg.goal.effector)[rows]
        worst = float(np.linalg.norm(at - np.asarray(seg.goal.position), axis=1).max())
        out.append((seg.provenance.origin.line, str(seg.goal.site), worst))
    return out


def reported_lines(sink: DiagnosticSink) -> set[int]:
    """Lines a hold miss may be reported at: verify's MT0511 (at the grasp or the reach) and
    MT0510 lines, and every MT0501's line (the hold pass's own MT0520 is retired)."""
    return {d.span.line for d in sink.items if d.code in ("MT0501", "MT0510", "MT0511")}


@pytest.mark.parametrize(("sex", "pct"), [("male", 50), ("female", 5)])
def test_parallel_trunk_reaches_keep_the_first_hand_on_its_site(
    tmp_path: Path, sex: str, pct: int
) -> None:
    ir, sink = compile_text(tmp_path, PARALLEL, sex, pct)
    misses = hold_misses(ir)
    assert 14 in {line for line, _, _ in misses}
    for line, site, worst in misses:
        assert worst <= 1e-3 or line in reported_lines(sink), (site, worst * 1000)
    left = next(w for line, _, w in misses if line == 14)
    assert left <= 1e-3, f"left hand {left * 1000:.1f} mm off low_left"  # was 1,000 mm
    # the motion is not jerkier for it: no one-frame step over 20 degrees
    assert ir.frames is not None
    assert np.degrees(np.abs(np.diff(ir.frames.q, axis=0))).max() < 20.0


@pytest.mark.parametrize(("sex", "pct"), [("female", 5), ("male", 95)])
def test_fuel_filter_bowl_stays_in_the_right_hand(sex: str, pct: int) -> None:
    ir, sink = compile_file(ROOT / "examples" / "replace_fuel_filter.mtask", sex, pct)
    misses = hold_misses(ir)
    bowl = [w for line, site, w in misses if line == 34 and site == "filter_bowl"]
    assert bowl and max(bowl) <= 1e-3, f"{max(bowl) * 1000:.1f} mm"  # was 121 / 75 mm
    for line, site, worst in misses:
        assert worst <= 1e-3 or line in reported_lines(sink), (line, site, worst * 1000)


def test_a_hold_the_kneel_cannot_keep_is_reported_once_by_verify(tmp_path: Path) -> None:
    ir, sink = compile_text(tmp_path, KNEEL, "male", 50)
    (lost,) = [d for d in sink.items if d.code == "MT0511"]
    assert lost.span.line == 13  # grasp(right): the grip that slips
    assert "during `behind_kneel > kneel`" in lost.message  # the motion that pulls it off
    assert not [d for d in sink.items if d.code == "MT0520"]  # retired: one fault, one warning
    (miss,) = hold_misses(ir)
    assert miss[2] > 0.1  # truly off: the report is not a false alarm
    off_mm = float(lost.message.split(" moves ")[1].split(" mm")[0])
    assert abs(off_mm - miss[2] * 1000) < 20  # the number it gives is what the frames show


CARRY = (
    HEAD
    + """scene rack {
    ground 0 cm
    site handle at (-20, 105, 45) cm normal (0, 0, -1)
    site knob at (55, 60, 60) cm normal (0, 1, 0)
    site exit at (0, 0, -200) cm
}

task hold_walk "Hold a part by two handles, walk away with it" {
    manikin gb10000_1988 female p5
    scene rack
    reach(right, handle)
    grasp(right)
    reach(left, knob)
    grasp(left)
    walk_to(exit)
    release(left)
    release(right)
}
"""
)


def test_a_part_held_in_both_hands_is_carried_whole_through_a_walk(tmp_path: Path) -> None:
    ir, _ = compile_text(tmp_path, CARRY, "female", 5)
    assert all(w <= 1e-3 for _, _, w in hold_misses(ir))  # held while standing
    frames = ir.frames
    assert frames is not None
    (walk,) = [s for s in ir.segments if s.kind == "locomotion"]
    rows = (frames.time >= walk.start) & (frames.time <= walk.end)
    pose = forward(ir.skeleton, frames.q[rows], frames.root_position[rows],
                   frames.root_rotation[rows])  # fmt: skip
    spread = np.linalg.norm(
        site_positions(ir.skeleton, pose, "r_hand") - site_positions(ir.skeleton, pose, "l_hand"),
        axis=1,
    )
    assert spread.max() - spread.min() <= 1e-3  # the hands do not move on the part


RELEASED_THEN_SQUAT = (
    HEAD
    + """scene s {
    site front at (-8, 132, 44) cm normal (-1, 0, 0)
}

task t {
    manikin gb10000_1988 male p95
    scene s
    pick(right, front)
    release(right)
    squat(70 cm)
    stand()
}
"""
)


def test_a_hand_that_let_go_is_free_and_its_fingertips_stay_above_the_floor(
    tmp_path: Path,
) -> None:
    """After ``release`` the hand holds nothing (``hold.on_site``), though no arm segment
    follows: the balance pass may turn its wrist to lift the fingertips. It took the hand for
    one still on its site (``hand_pins`` pins until the arm's next segment), and the squat put
    the fingertips 74 mm through the floor (generated gen_146, MT0525 and MT0512; MT0525 is
    retired since)."""
    from mtlc.passes.hold import on_site

    path = tmp_path / "t.mtask"
    path.write_text(RELEASED_THEN_SQUAT, encoding="utf-8")
    (timeline,) = run_frontend([path]).timelines
    sink = DiagnosticSink()
    ir = run_motion(timeline, sink)
    assert not {"MT0512", "MT0525"} & {d.code for d in sink.items}, sink.items
    fr = ir.frames
    assert fr is not None
    pose = forward(ir.skeleton, fr.q, fr.root_position, fr.root_rotation)
    tips = site_positions(ir.skeleton, pose, ["r_fingertip", "l_fingertip"])
    assert tips[..., 1].min() > ir.ground - 1e-3
    (to,) = [s for s in ir.on_track("r_arm") if s.kind == "TO"]
    held = on_site(ir, fr.time)["r_hand"]
    assert held[(fr.time > to.start) & (fr.time < to.end)].all()
    assert not held[fr.time > to.end + 1.0].any()  # let go: free for the squat


def _faded(until: float) -> tuple[np.ndarray, np.ndarray]:
    from mtlc.body.skeleton import build_manikin
    from mtlc.ir.model import Frames
    from mtlc.passes.hold import _fade

    skel = build_manikin("gb10000_1988", "male", 50)
    t = np.arange(0.0, 2.0, 1 / 60)
    n = t.size
    frames = Frames(
        60.0, t, np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, skel.n_dofs))
    )
    delta = np.zeros(skel.n_dofs)
    delta[skel.dof_index("r_shoulder_flex")] = 0.3
    _fade(skel, frames, 0.2, 0.5, delta, until)  # kept from 0.2 s, let go from 0.5 s
    return t, frames.q[:, skel.dof_index("r_shoulder_flex")]


def test_a_holds_correction_fades_from_rest_to_rest() -> None:
    # a linear ramp started the arm at its full rate in the frame the hold ended: a move that
    # left from rest there went 18 cm/s in its first frame (issue 19)
    t, q = _faded(np.inf)
    steps = np.abs(np.diff(q))
    assert q[(t > 0.2) & (t < 0.5)] == pytest.approx(0.3)  # kept until the hold ends
    assert steps[np.searchsorted(t, 0.5)] < 0.1 * steps.max()  # starts from rest
    assert q[-1] == 0.0 and steps[-5:].max() == 0.0
    # a next hold that starts before the ramp would end: the ramp ends there, not cut off by it
    t, q = _faded(0.7)
    assert np.all(q[t >= 0.7 - 1e-9] == 0.0)
    assert np.abs(np.diff(q[t > 0.3])).max() < 0.3 / 4
