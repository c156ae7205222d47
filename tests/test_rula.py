"""RULA scorer: bands, tables and whole postures against scores worked by hand from the
worksheet (McAtamney & Corlett 1993)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward
from mtlc.ergonomics import rula


@pytest.fixture(scope="module")
def skel():  # type: ignore[no-untyped-def]
    return build_manikin("gb10000_1988", "male", 50)


def _score(skel, **angles_deg: float) -> dict[str, rula.RulaScores]:  # type: ignore[no-untyped-def]
    q = np.zeros((1, len(skel.dof_names)))
    for name, deg in angles_deg.items():
        q[0, skel.dof_names.index(name)] = math.radians(deg)
    pose = forward(skel, q, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0, 0.0]]))
    return rula.score_frames(skel, pose, q, np.array([True]))


def test_tables_have_every_cell_filled_and_in_range() -> None:
    for table, top in ((rula.table_a(), 9), (rula.table_b(), 9), (rula.table_c(), 7)):
        assert table.min() >= 1 and table.max() <= top


@pytest.mark.parametrize(
    ("band", "angle", "score"),
    [
        (rula.upper_arm_band, -25, 2), (rula.upper_arm_band, -20, 1), (rula.upper_arm_band, 20, 1),
        (rula.upper_arm_band, 30, 2), (rula.upper_arm_band, 60, 3), (rula.upper_arm_band, 120, 4),
        (rula.lower_arm_band, 30, 2), (rula.lower_arm_band, 80, 1), (rula.lower_arm_band, 110, 2),
        (rula.wrist_band, 0, 1), (rula.wrist_band, -10, 2), (rula.wrist_band, 30, 3),
        (rula.neck_band, 5, 1), (rula.neck_band, 15, 2), (rula.neck_band, 25, 3), (rula.neck_band, -5, 4),
        (rula.trunk_band, 0, 1), (rula.trunk_band, 15, 2), (rula.trunk_band, 40, 3), (rula.trunk_band, 70, 4),
    ],
)  # fmt: skip
def test_bands(band, angle: float, score: int) -> None:  # type: ignore[no-untyped-def]
    assert int(band(np.array([angle]))[0]) == score


def test_table_lookups_worked_by_hand() -> None:
    # Table A row "upper arm 3, lower arm 2": wrist 3, twist 2 -> 4; table B neck 2, trunk 3, legs 1 -> 4
    assert rula.table_a()[2, 1, 2, 1] == 4
    assert rula.table_b()[1, 2, 0] == 4
    # table C: C = 4 + 1 muscle + 1 force = 6, D = 4 + 2 = 6 -> 7
    assert int(rula.grand_score(np.array([4]), np.array([4]), muscle=1, force=1)[0]) == 7
    # C and D past the table are clamped to its last row and column (8, 7) -> 7
    assert int(rula.grand_score(np.array([9]), np.array([9]))[0]) == 7


def test_standing_at_rest(skel) -> None:  # type: ignore[no-untyped-def]
    """Arms hanging, elbows straight: upper arm 1, lower arm 2 (0° is outside 60–100), wrist 1,
    twist 1 -> A = 2; neck 1, trunk 1, legs 1 -> B = 1; grand C[2, 1] = 2."""
    s = _score(skel)["r"]
    got = [int(x[0]) for x in (s.upper_arm, s.lower_arm, s.wrist, s.wrist_twist, s.score_a,
                               s.neck, s.trunk, s.legs, s.score_b, s.grand)]  # fmt: skip
    assert got == [1, 2, 1, 1, 2, 1, 1, 1, 1, 2]


def test_reaching_forward_and_up_with_a_bent_neck(skel) -> None:  # type: ignore[no-untyped-def]
    """Shoulder 100° flexion (4), elbow 80° (1), wrist 30° (3), forearm near end of pronation
    (2) -> A[4,1,3,2] = 5. Neck 25° flexion (3), trunk erect (1), legs 1 -> B[3,1,1] = 3.
    Grand C[5, 3] = 4."""
    s = _score(skel, r_shoulder_flex=100, r_elbow_flex=80, r_wrist_flex=30, r_elbow_pro=75,
               neck_flex=25)["r"]  # fmt: skip
    got = [int(x[0]) for x in (s.upper_arm, s.lower_arm, s.wrist, s.wrist_twist, s.score_a,
                               s.neck, s.trunk, s.score_b, s.grand)]  # fmt: skip
    assert got == [4, 1, 3, 2, 5, 3, 1, 3, 4]


def test_bent_and_twisted_trunk_on_one_foot(skel) -> None:  # type: ignore[no-untyped-def]
    """Trunk 45° forward (lumbar 30 + thorax 15: 3) twisted 15° (+1) -> 4; neck 0 (1); one foot
    (legs 2) -> B[1,4,2] = 5."""
    q = np.zeros((1, len(skel.dof_names)))
    for name, deg in (("lumbar_flex", 30), ("thorax_flex", 15), ("thorax_rot", 15)):
        q[0, skel.dof_names.index(name)] = math.radians(deg)
    pose = forward(skel, q, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0, 0.0]]))
    s = rula.score_frames(skel, pose, q, np.array([False]))["l"]
    assert (int(s.trunk[0]), int(s.legs[0]), int(s.score_b[0])) == (4, 2, 5)


def test_a_sideways_raised_arm_scores_by_elevation_and_abduction(skel) -> None:  # type: ignore[no-untyped-def]
    """90° of abduction: elevation 90° (3) + abducted (+1) = 4, and the forearm works out to the
    side (lower arm 2 + 1 = 3)."""
    s = _score(skel, l_shoulder_abd=90)["l"]
    assert (int(s.upper_arm[0]), int(s.lower_arm[0])) == (4, 3)


@given(st.integers(1, 12), st.integers(1, 12), st.integers(0, 1), st.integers(0, 3))
def test_grand_score_is_monotone(a: int, b: int, muscle: int, force: int) -> None:
    """A worse posture never lowers the grand score, and it stays in 1–7."""
    g = int(rula.grand_score(np.array([a]), np.array([b]), muscle, force)[0])
    assert 1 <= g <= 7
    assert int(rula.grand_score(np.array([a + 1]), np.array([b]), muscle, force)[0]) >= g
    assert int(rula.grand_score(np.array([a]), np.array([b + 1]), muscle, force)[0]) >= g


def test_action_levels() -> None:
    assert rula.action_level(np.array([1, 2, 3, 4, 5, 6, 7])).tolist() == [1, 1, 2, 2, 3, 3, 4]


# -- repetition: a fastener's strokes or grips (muscle use +1, 2-10 kg scores 2) --------------


def test_four_a_minute_is_repeated_and_one_action_never_is() -> None:
    # rula_bands.csv, muscle_use: "action repeated >=4 times/min"
    assert rula.repetition_rate(18, 270.0) == pytest.approx(4.0)
    assert rula.Repetition("r", "bolt", 18, 0.0, 270.0).repeated  # exactly 4 a minute
    assert not rula.Repetition("r", "bolt", 18, 0.0, 271.0).repeated  # 3.99 a minute
    assert not rula.Repetition("r", "bolt", 1, 0.0, 0.5).repeated  # 120 a minute, but once


@given(st.integers(2, 200), st.floats(0.1, 3600.0))
def test_repeated_iff_at_least_four_a_minute(count: int, seconds: float) -> None:
    rep = rula.Repetition("l", "nut", count, 10.0, 10.0 + seconds)
    assert rep.repeated == (count / (seconds / 60.0) >= rula.REPEATED_PER_MIN - 1e-9)


def _wrench_ir(tmp_path, setting: str, turns: int, args: str = ""):  # type: ignore[no-untyped-def]
    from test_tools import _timeline

    from mtlc.passes import lower

    return lower(_timeline(tmp_path, setting, turns=turns, args=args))


def test_wrench_strokes_worked_example(tmp_path, skel) -> None:  # type: ignore[no-untyped-def]
    """3 turns at 60° with a 3 kg load: 18 strokes back to back, N = 18 × d seconds (d one
    stroke's MTM time) -> 18 / (N / 60) a minute, far above 4: muscle use +1 and force/load 2
    (3.06 kg, repeated) from the first stroke's start to the last's end, right hand only; the
    load is in the hand from the grasp to the release (force/load 1 around the strokes)."""
    ir = _wrench_ir(tmp_path, "tool wrench_10mm", 3, ", load: 3 kg")
    strokes = sorted((s for s in ir.segments if "stroke" in s.goal.params), key=lambda s: s.start)
    d = strokes[0].end - strokes[0].start
    n_seconds = 18 * d  # back to back: each starts where the one before ends
    (rep,) = rula.repetitions(ir)
    assert (rep.side, rep.site, rep.count) == ("r", "bolt", 18)
    assert rep.end - rep.start == pytest.approx(n_seconds, abs=1e-9)
    assert rep.per_minute == pytest.approx(18 * 60 / n_seconds)  # 95.3 a minute here
    assert rep.per_minute > 90.0 and rep.repeated
    # the score changes at the first stroke's first frame: one frame before it and one at it
    t = np.array([rep.start - 0.05, rep.start, 0.5 * (rep.start + rep.end), rep.end + 0.05])
    muscle, force = rula.muscle_scores(ir, t), rula.force_scores(ir, t)
    assert muscle["r"].tolist() == [0, 1, 1, 0] and muscle["l"].tolist() == [0, 0, 0, 0]
    # 3.06 kg: intermittent (1) in the hand from the grasp before the strokes to the release
    # after them (mtlc.loads), repeated (2) while stroking
    assert force["r"].tolist() == [1, 2, 2, 1]
    assert force["l"].tolist() == [0, 0, 0, 0]
    # the grand score at those frames, in one posture: C = A + muscle + force, D = B + ...
    q = np.tile(skel.q_comfort, (len(t), 1))
    pose = forward(skel, q)
    feet = np.ones(len(t), dtype=bool)
    bare = rula.score_frames(skel, pose, q, feet)["r"]
    scored = rula.score_frames(skel, pose, q, feet, muscle=muscle, force=force)["r"]
    a, b = int(bare.score_a[0]), int(bare.score_b[0])
    before = rula.table_c()[min(a + 1, 8) - 1, min(b + 1, 7) - 1]  # force 1: the load held
    during = rula.table_c()[min(a + 3, 8) - 1, min(b + 3, 7) - 1]
    assert scored.grand.tolist() == [before, during, during, before]
    assert during > before


def test_repetition_without_a_tool_is_not_counted(tmp_path) -> None:  # type: ignore[no-untyped-def]
    ir = _wrench_ir(tmp_path, "", 1)  # bare-hand quarter turns: no strokes, no tool grips
    assert rula.repetitions(ir) == []
    t = np.linspace(0.0, max(s.end for s in ir.segments), 50)
    assert all(m.max() == 0 for m in rula.muscle_scores(ir, t).values())


def test_screwdriver_grips_worked_example(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """One turn with a screwdriver: 4 quarter turns of 3 grips each (docs/tools.md) = 12 grips
    over the 4 twists' window: repeated. The screwdriver weighs 0.08 kg: force/load stays 0."""
    from test_tools import _timeline

    from mtlc.diagnostics import DiagnosticSink
    from mtlc.passes import run_motion

    ir = run_motion(_timeline(tmp_path, "tool screwdriver_flat", turns=1), DiagnosticSink())
    twists = sorted(
        (s for s in ir.segments if s.goal.params.get("posture") == "twist"), key=lambda s: s.start
    )
    assert [s.result["grips"] for s in twists] == [3, 3, 3, 3]
    (rep,) = rula.repetitions(ir)
    assert (rep.side, rep.site, rep.count) == ("r", "bolt", 12)
    assert (rep.start, rep.end) == (twists[0].start, twists[-1].end)
    assert rep.per_minute == pytest.approx(12 * 60 / (twists[-1].end - twists[0].start))
    t = np.array([twists[0].start - 0.05, twists[1].start, twists[-1].end + 0.05])
    assert rula.muscle_scores(ir, t)["r"].tolist() == [0, 1, 0]
    assert rula.force_scores(ir, t)["r"].tolist() == [0, 0, 0]
