"""Issue 18 item 2: carried loads in the centre of mass, the strict support, fingertips up."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, center_of_mass, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.loads import carried_com, carried_loads, held_load
from mtlc.metrics import (
    FOREFOOT_SLOTS,
    KNEE_SLOTS,
    SOLE_SLOTS,
    SUPPORT_TOL,
    compute_metrics,
    hand_contacts,
    support,
)
from mtlc.passes import lower, run_motion

SKEL = build_manikin("gb10000_1988", "male", 50)
REF = SourceRef("synthetic.mtask", 3, 5, 3, 20)
PROV = Provenance(("t", "a", "e"), REF, REF)

LIFT = """use stdlib.actions
use stdlib.elements

scene bench {
    ground 0 cm
    site crate at (20, 40, 45) cm normal (0, 1, 0)
    site shelf at (30, 110, 50) cm normal (0, 1, 0)
}

task lift_crate {
    manikin gb10000_1988 male p50
    scene bench
    lift(crate, shelf, load: LOAD kg)
    hold(2 s)
}
"""

SQUAT = """use stdlib.actions
use stdlib.elements

scene low {
    ground 0 cm
    site work at (0, 0, 40) cm
    site valve at (10, 18, 80) cm normal (0, 1, 0)
}

task low_valve {
    manikin gb10000_1988 female p50
    scene low
    walk_to(work)
    squat(0 cm)
    look(valve)
    reach(right, valve)
    grasp(right)
    turn(right, -90 deg)
    release(right)
    stand()
}
"""


def _timeline(tmp_path: Path, text: str, name: str = "task.mtask") -> object:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors, program.sink.items
    return program.timelines[0]


def _motion(tmp_path: Path, text: str) -> tuple[MotionIR, list]:
    timeline = _timeline(tmp_path, text)
    sink = DiagnosticSink()
    return run_motion(timeline, sink), [d.code for d in sink.items]


# -- loads -------------------------------------------------------------------------------------


def test_a_lifted_part_is_held_from_the_grasp_to_the_end_half_in_each_hand(tmp_path: Path) -> None:
    ir = lower(_timeline(tmp_path, LIFT.replace("LOAD", "9")))
    grasp = [s for s in ir.segments if s.kind == "grip" and s.goal.params["state"] == "closed"]
    end = max(s.end for s in ir.segments)
    loads = carried_loads(ir)
    assert sorted(x.side for x in loads) == ["l", "r"]
    for load in loads:
        assert load.mass == 9.0 and load.share == 4.5  # two hands carry it
        assert load.start == pytest.approx(min(g.start for g in grasp))
        assert load.end == pytest.approx(end)  # no release: held to the end
    t = np.array([0.0, grasp[0].start + 1e-3, end])
    kg = held_load(ir, t)
    assert kg["r"].tolist() == [0.0, 9.0, 9.0] == kg["l"].tolist()  # RULA: the load handled


def test_a_release_ends_the_hold_and_the_load_sits_at_the_grip(tmp_path: Path) -> None:
    to = Segment("r_arm", "TO", 1.0, 2.0, GoalSpec("r_hand", "a", params={"load": 5.0}), PROV)
    close = Segment("r_hand", "grip", 0.5, 0.8, GoalSpec("r_hand", None, params={"state": "closed"}), PROV)  # fmt: skip
    open_ = Segment("r_hand", "grip", 2.5, 2.7, GoalSpec("r_hand", None, params={"state": "open"}), PROV)  # fmt: skip
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [close, to, open_], SKEL)
    ((load,),) = [carried_loads(ir)]
    assert (load.start, load.end, load.share) == (0.5, 2.7, 5.0)
    time = np.array([0.4, 1.5, 2.8])
    pose = forward(SKEL, np.tile(SKEL.q_comfort, (3, 1)))
    com = carried_com(ir, pose, time)
    bare = center_of_mass(SKEL, pose)
    hand = site_positions(SKEL, pose, "r_hand")
    big = SKEL.total_mass
    np.testing.assert_allclose(com[[0, 2]], bare[[0, 2]], atol=0.0)  # outside: nothing
    np.testing.assert_allclose(com[1], (big * bare[1] + 5.0 * hand[1]) / (big + 5.0), atol=1e-12)


def test_a_heavy_load_changes_the_motion_or_is_reported(tmp_path: Path) -> None:
    light, _ = _motion(tmp_path, LIFT.replace("LOAD", "2"))
    heavy, codes = _motion(tmp_path, LIFT.replace("LOAD", "40"))
    assert not np.array_equal(light.frames.q, heavy.frames.q)  # the balance pass answers it
    lm, hm = compute_metrics(light), compute_metrics(heavy)
    assert hm.support_margin_static < lm.support_margin_static - 0.01
    if hm.support_margin_static < 0.0:
        assert "MT0502" in codes  # never silent


# -- the strict support ------------------------------------------------------------------------


def _standing_pose(heel_up: float) -> tuple[np.ndarray, object]:
    """The comfort pose with the right foot pitched so its heel is ``heel_up`` above its toe,
    the lowest sole point on y = 0."""
    q = np.asarray(SKEL.q_comfort, dtype=float).copy()
    k = SKEL.dof_index("r_ankle_dorsi")

    def rise(a: float) -> float:
        q[k] = a
        pose = forward(SKEL, q[None])
        heel, toe = site_positions(SKEL, pose, ["r_heel", "r_toe"])[0, :, 1]
        return float(heel - toe)

    lo, hi = -0.5, 0.1  # plantar flexion raises the heel; the level foot is in between
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if rise(mid) < heel_up else (mid, hi)
    q[k] = 0.5 * (lo + hi)
    pose = forward(SKEL, q[None])
    low = site_positions(SKEL, pose, [f"{s}_{p}" for s in "rl" for p in ("heel", "toe")])[0]
    root = np.asarray(SKEL.root_position, dtype=float) - np.array([0.0, low[:, 1].min(), 0.0])
    return q, forward(SKEL, q[None], root[None])


@pytest.mark.parametrize(("heel_up", "counts"), [(0.0015, True), (0.003, False), (0.03, False)])
def test_a_sole_point_supports_only_within_2_mm(heel_up: float, counts: bool) -> None:
    _, pose = _standing_pose(heel_up)
    _, ok = support(SKEL, pose, np.ones((1, 2), dtype=bool), 0.0)
    heel, toe = ok[0, SOLE_SLOTS][0], ok[0, SOLE_SLOTS][1]
    assert toe and heel == counts
    assert not ok[0, FOREFOOT_SLOTS].any()  # a rigid foot on its toe: no virtual forefoot


@pytest.mark.parametrize(("above", "counts"), [(0.0, True), (0.0019, True), (0.0025, False)])
def test_a_knee_supports_when_its_front_is_within_2_mm(above: float, counts: bool) -> None:
    q = np.asarray(SKEL.q_comfort, dtype=float)
    pose = forward(SKEL, q[None])
    knee = pose.p[0, SKEL.joint_index("r_knee"), 1]
    ground = knee - 0.05 - above  # the knee's front (5 cm below its centre) `above` it
    _, ok = support(SKEL, pose, np.zeros((1, 2), dtype=bool), float(ground))
    assert bool(ok[0, KNEE_SLOTS][:2].all()) == counts


def test_a_hand_supports_only_within_2_mm_of_its_site() -> None:
    q = np.tile(SKEL.q_comfort, (3, 1))
    root = np.tile(SKEL.root_position, (3, 1))
    hand = site_positions(SKEL, forward(SKEL, q[:1], root[:1]), "r_hand")[0]
    to = Segment("r_arm", "TO", 0.0, 0.5, GoalSpec("r_hand", "a", position=hand), PROV)
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [to], SKEL)
    root[1, 1] += 0.5 * SUPPORT_TOL  # 1 mm off its site: still on it
    root[2, 1] += 0.05  # 5 cm off: bears nothing
    pose = forward(SKEL, q, root)
    t = np.array([0.6, 0.7, 0.8])
    assert hand_contacts(ir, t).all(axis=0).tolist() == [True, False]  # the window alone
    assert hand_contacts(ir, t, pose)[:, 0].tolist() == [True, True, False]


# -- postures and fingertips -------------------------------------------------------------------


def test_standing_up_ends_on_level_soles() -> None:
    from mtlc.passes.posture import target_posture

    q = target_posture(SKEL, np.asarray(SKEL.q_comfort, dtype=float), {"posture": "stand"})
    pose = forward(SKEL, q[None])
    soles = site_positions(SKEL, pose, [f"{s}_{p}" for s in "rl" for p in ("heel", "toe")])[0]
    assert np.ptp(soles[:, 1]) < 1e-3  # heels and toes on the floor together


def test_a_deep_squat_keeps_the_fingertips_above_the_floor(tmp_path: Path) -> None:
    ir, _ = _motion(tmp_path, SQUAT)
    f = ir.frames
    pose = forward(ir.skeleton, f.q, f.root_position, f.root_rotation)
    tips = site_positions(ir.skeleton, pose, ["r_fingertip", "l_fingertip"])[..., 1]
    assert tips.min() >= ir.ground - 1e-3  # 102 mm under before issue 18
    jumps = np.degrees(np.abs(np.diff(f.q, axis=0)))
    for dof in ("r_shoulder_flex", "l_shoulder_flex", "r_wrist_flex", "l_wrist_flex"):
        assert jumps[:, ir.skeleton.dof_index(dof)].max() < 20.0, dof


FLOOR_PLATE = """use stdlib.actions
use stdlib.elements

scene hangar_floor {
    site front at (0, 0, 40) cm
    site floor_plate at (25, 1, 45) cm normal (1, 0, 0)
    site ahead at (0, 0, 90) cm
}

task touch_floor_plate {
    manikin gb10000_1988 male p50
    scene hangar_floor
    travel_facing(front, ahead)
    squat(0 cm)
    reach(right, floor_plate)
    stand()
}
"""


def test_fingertips_that_cannot_be_lifted_are_reported(tmp_path: Path) -> None:
    """Once, by verify (MT0512): the balance pass's own MT0525 for the same fault is retired
    (this was the example of its page). The body faces ahead, the plate 25 cm to its side:
    walking to face it, the plate is in front of the knees and the squat stands wide, which
    stops the hand 85 mm short with the fingertips above the floor (MT0501 only)."""
    ir, codes = _motion(tmp_path, FLOOR_PLATE)
    assert "MT0512" in codes and "MT0525" not in codes
    f = ir.frames
    pose = forward(ir.skeleton, f.q, f.root_position, f.root_rotation)
    tips = site_positions(ir.skeleton, pose, ["r_fingertip", "l_fingertip"])[..., 1]
    assert tips.min() < ir.ground - 1e-3  # what it reports is there
    assert math.isfinite(float(tips.min()))


def test_a_load_is_taken_up_and_put_down_gradually() -> None:
    from mtlc.loads import LOAD_RAMP, Load, load_weight

    load = Load("r", 40.0, 40.0, 1.0, 3.0)
    t = np.array([0.9, 1.0, 1.0 + LOAD_RAMP / 2, 1.0 + LOAD_RAMP, 2.0, 3.0 - LOAD_RAMP / 2, 3.1])
    np.testing.assert_allclose(load_weight(load, t), [0.0, 0.0, 0.5, 1.0, 1.0, 0.5, 0.0])
    short = Load("r", 1.0, 1.0, 0.0, 0.2)  # shorter than two ramps: up and down in it
    assert load_weight(short, np.array([0.1]))[0] == pytest.approx(1.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), count=st.integers(1, 12))
def test_many_loads_in_one_hand_weigh_as_each_one_placed_by_itself(seed: int, count: int) -> None:
    """``carried_com`` places each hand once for all its loads: the same numbers, to the bit,
    as placing the hand again for every load (the per-load sum it replaced)."""
    from mtlc.loads import Held, Load, load_weight

    rng = np.random.default_rng(seed)
    n = 30
    q = np.clip(SKEL.q_comfort + rng.normal(0.0, 0.3, (n, SKEL.n_dofs)), SKEL.lower, SKEL.upper)
    pose = forward(SKEL, q)
    t = np.sort(rng.uniform(0.0, 10.0, n))
    loads = []
    for _ in range(count):
        start = float(rng.uniform(0.0, 9.0))
        mass = float(rng.uniform(0.1, 40.0))
        side = "r" if rng.random() < 0.5 else "l"
        loads.append(Load(side, mass, mass / 2, start, start + float(rng.uniform(0.1, 3.0))))
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [], SKEL)
    got = carried_com(ir, pose, t, Held([], loads))
    big_m = float(SKEL.total_mass)
    moment, mass = big_m * center_of_mass(SKEL, pose), np.full(n, big_m)
    for load in loads:
        held_mass = load.share * load_weight(load, t)
        if held_mass.any():
            moment += held_mass[:, None] * site_positions(SKEL, pose, f"{load.side}_hand")
            mass += held_mass
    assert np.array_equal(got, moment / mass[:, None])
