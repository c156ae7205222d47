"""A reach that needs a lean while the other hand holds its site (session 12): MT0501 only when
no pose meets the goal, the hands where the frames say, the trunk not leaned more than needed.

Main stopped a PSU latch reach (tests/data/lean/l04, male P50) 1.1 mm short at 90 deg of trunk
flexion and reported it unreachable, though poses that meet both the latch and the held handle
exist: the damped least-squares descent's pull to upright fades as the error goes to 0 and it
stopped where it stopped. Each verdict here is checked against an independent multi-start
solve (``solve_ta`` from 48 random poses, with restarts) of the same two goals.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on

from mtlc.body import forward, site_positions
from mtlc.body.ik import Goal, prepare, solve_ta
from mtlc.diagnostics import DiagnosticSink
from mtlc.ir.model import MotionIR
from mtlc.passes.hold import hold_spans

DATA = Path(__file__).resolve().parents[1] / "data" / "lean"
PROCEDURES = sorted(p.name for p in DATA.glob("*.mtask"))
MANIKINS = [("female", 5), ("male", 50), ("male", 95)]
TOL = 1e-3  # m: the contact claim (MT0501 beyond it)
STARTS = 48
LEAN_SLACK = 10.0  # deg over the least flexion any of the independent solutions needs


def compile_file(path: Path, sex: str, pct: int) -> tuple[MotionIR, DiagnosticSink]:
    return compile_on(path, (sex, pct))


def flexion(ir: MotionIR, q: np.ndarray) -> np.ndarray:
    names = list(ir.skeleton.dof_names)
    lumbar, thorax = names.index("lumbar_flex"), names.index("thorax_flex")
    return np.degrees(q[..., lumbar] + q[..., thorax])


def independent_solutions(
    ir: MotionIR, goals: list[Goal], q0: np.ndarray, root: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """(poses, their worst goal distance) of ``solve_ta`` from ``STARTS`` random poses (and the
    body as it is), the trunk and both arms free: what the body can do, by another road."""
    skel = ir.skeleton
    rng = np.random.default_rng(7)
    single = prepare(skel, goals, q0, reach="torso")
    lo, hi = skel.lower[single.active], skel.upper[single.active]
    qs = np.tile(q0, (STARTS, 1))
    qs[1:, single.active] = lo + (hi - lo) * rng.random((STARTS - 1, len(single.active)))
    batch = [Goal(g.effector, position=np.tile(g.position, (STARTS, 1))) for g in goals]
    model = prepare(
        skel, batch, qs, reach="torso", root_position=np.tile(root[0], (STARTS, 1)),
        root_rotation=np.tile(root[1], (STARTS, 1)),
    )  # fmt: skip
    res = solve_ta(skel, batch, qs, model=model, restarts=3, max_iter=200, tol=5e-4)
    return res.q, res.position_error


@pytest.mark.parametrize("procedure", PROCEDURES)
@pytest.mark.parametrize(("sex", "pct"), MANIKINS)
def test_a_held_reach_is_short_only_when_no_pose_meets_it(
    procedure: str, sex: str, pct: int
) -> None:
    ir, sink = compile_file(DATA / procedure, sex, pct)
    skel, frames = ir.skeleton, ir.frames
    assert frames is not None
    pose = forward(skel, frames.q, frames.root_position, frames.root_rotation)
    spans = hold_spans(ir)
    short = {d.span.line for d in sink.items if d.code == "MT0501"}
    reaches = [s for s in ir.segments if s.kind == "TO" and s.track == "r_arm"]
    assert reaches
    held = [(c, end) for c, end in spans if c.track == "l_arm"]
    assert held
    contact = held[0][0]
    reach = reaches[0]
    i = int(np.argmin(np.abs(frames.time - reach.end)))
    off = float(np.linalg.norm(site_positions(skel, pose, "r_hand")[i] - reach.goal.position))
    # the held hand, on its site from its grip to the end of the other hand's reach
    rows = (frames.time >= contact.end - 1e-6) & (frames.time <= reach.end + 1e-6)
    at = site_positions(skel, pose, "l_hand")[rows]
    worst = float(np.linalg.norm(at - np.asarray(contact.goal.position), axis=1).max())
    assert worst <= TOL, f"held hand {worst * 1000:.2f} mm off its site"
    # an independent answer to "can both goals be met?"
    goals = [
        Goal("r_hand", position=np.asarray(reach.goal.position, dtype=float)),
        Goal("l_hand", position=np.asarray(contact.goal.position, dtype=float)),
    ]
    root = (frames.root_position[i], frames.root_rotation[i])
    qs, err = independent_solutions(ir, goals, frames.q[i], root)
    line = reach.provenance.origin.line
    if line in short:
        assert off > TOL  # the verdict is what the frames show
        assert err.min() > TOL, f"reported short, but a pose meets both ({err.min() * 1000:.2f} mm)"
        return
    assert off <= TOL, f"the right hand {off * 1000:.2f} mm off, not reported"
    met = err <= TOL
    if met.any():  # not leaned much further than some pose that meets both needs
        least = float(flexion(ir, qs[met]).min())
        assert flexion(ir, frames.q[i]) <= least + LEAN_SLACK, (flexion(ir, frames.q[i]), least)
