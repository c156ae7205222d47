"""The pace pass: a reach is one minimum-jerk movement (Flash & Hogan 1985) from the start of its
approach to contact, measured on the frames a user receives (issue 19)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.pace import minimum_jerk, movements, smooth_path
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

REACH = """use stdlib.actions
use stdlib.elements

scene bench {
    ground 0 cm
    site valve at (-12, 100, 45) cm normal (0, 1, 0)
    site knob at (25, 120, 40) cm normal (0, 0, -1)
}

task two_reaches "Reach a valve from above, then a knob from the front" {
    manikin gb10000_1988 male p50
    scene bench
    reach(right, valve)
    grasp(right)
    release(right)
    reach(left, knob)
    hold(1 s)
}
"""


def test_minimum_jerk_profile() -> None:
    tau = np.linspace(0.0, 1.0, 101)
    s = minimum_jerk(tau)
    assert s[0] == 0.0 and s[-1] == 1.0 and s[50] == pytest.approx(0.5)
    v = np.gradient(s, tau)
    assert np.all(np.diff(s) >= 0.0)
    assert v[0] == pytest.approx(0.0, abs=1e-3) and v[-1] == pytest.approx(0.0, abs=1e-3)
    assert v.max() == pytest.approx(1.875, abs=1e-3)  # Flash & Hogan's peak, 1.875 x mean


def test_smooth_path_keeps_its_ends_and_removes_a_zigzag() -> None:
    n = np.arange(101, dtype=float)
    line = np.stack([n / 100.0, -n / 50.0], axis=1)
    zigzag = line + 0.02 * np.where(n % 2 == 0, 1.0, -1.0)[:, None] * (n > 60)[:, None]
    out = smooth_path(zigzag, 3.0)
    assert np.allclose(out[0], zigzag[0], atol=1e-12)
    assert np.allclose(out[-1], zigzag[-1], atol=1e-12)
    assert np.abs(out - line)[:90].max() < 0.002  # the zig-zag is gone, the line kept


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> MotionIR:
    path = tmp_path_factory.mktemp("pace") / "reaches.mtask"
    path.write_text(REACH)
    program = run_frontend([path])
    assert not program.sink.has_errors, [d.message for d in program.sink.items]
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "male", 50))
    return run_motion(timeline, DiagnosticSink(), MotionOptions())


def test_each_reach_is_one_bell_and_slow_at_contact(compiled: MotionIR) -> None:
    ir = compiled
    frames = ir.frames
    assert frames is not None
    dt = 1.0 / frames.fps
    pose = forward(ir.skeleton, frames.q, frames.root_position, frames.root_rotation)
    moves = movements(ir)
    assert len(moves) == 2 and all(len(m.segments) == 2 for m in moves)  # TA + TO each
    for m in moves:
        (effector,) = m.effectors
        assert [s.result.get("paced") for s in m.segments] == ["minimum_jerk"] * 2
        a = int(np.searchsorted(frames.time, m.start - 1e-9))
        b = int(np.searchsorted(frames.time, m.end - 1e-9))
        p = site_positions(ir.skeleton, pose, effector)[a : b + 1]
        speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
        padded = np.concatenate([[0.0], speed, [0.0]])
        peaks, _ = find_peaks(padded, prominence=0.1 * speed.max())
        assert len(peaks) == 1, np.round(speed * 100, 1)
        assert speed[-1] <= 0.05  # m/s in the frame where contact is made
        site = m.segments[-1].goal.position
        assert np.linalg.norm(p[-1] - site) <= 1e-3  # still on the site


def test_a_long_movement_is_measured_at_most_max_path_samples() -> None:
    """480 samples a second for a person's reach; a fuzzed reach of 93 s (a long hold) took
    44,000 and the pass's whole time: it is measured at 4,096 (issue 21)."""
    from mtlc.passes.pace import MAX_PATH_SAMPLES, MIN_PATH_SAMPLES, Movement, path_grid

    assert len(path_grid(Movement([], 1.0, 2.5))) == 721  # 1.5 s at 480 a second
    assert len(path_grid(Movement([], 1.0, 1.01))) == MIN_PATH_SAMPLES + 1
    long = path_grid(Movement([], 0.26, 93.33))
    assert len(long) == MAX_PATH_SAMPLES + 1
    assert long[0] == 0.26 and long[-1] == 93.33


@pytest.mark.parametrize(("sex", "percentile"), [("male", 99), ("female", 5)])
def test_a_part_in_both_hands_is_carried_rigid_before_the_carry_pass(
    sex: str, percentile: int
) -> None:
    """tests/data/arms a02: a box held in both hands from a low shelf to a high one and down.
    The two arms' keys, interpolated each on its own, squeezed it by 198 mm (male P99) and
    119 mm (female P5) between them; the pace pass makes the carried path rigid before timing
    it, so the carry pass's per-frame correction has little left to do."""
    from pathlib import Path

    from mtlc.passes.carry import carries

    path = Path(__file__).resolve().parents[2] / "tests/data/arms/a02_two_hands_high_low.mtask"
    (timeline,) = run_frontend([path]).timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", sex, percentile))
    ir = run_motion(timeline, DiagnosticSink(), MotionOptions(), until="interpolate")
    frames = ir.frames
    assert frames is not None
    spans = carries(ir)
    assert spans
    for carry in spans:
        rows = (frames.time >= carry.start) & (frames.time < carry.end)
        pose = forward(ir.skeleton, frames.q[rows], frames.root_position[rows],
                       frames.root_rotation[rows])  # fmt: skip
        hands = site_positions(ir.skeleton, pose, ["r_hand", "l_hand"])
        apart = np.linalg.norm(hands[:, 0] - hands[:, 1], axis=1)
        assert np.abs(apart - apart[0]).max() < 0.03  # m
