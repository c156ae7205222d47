"""The segment-reading helpers of the balance pass (issue 21): bisected and vectorised, each
equal to the per-segment scan it replaced (kept here as the reference), on random timelines."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward, site_positions
from mtlc.ir.model import GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.loads import EPS, Load, _grips, _motion_end, carried_com, carried_loads, held
from mtlc.metrics import (
    ARM_TRACKS,
    FEET,
    STEPPING_KINDS,
    SUPPORT_TOL,
    _reachable,
    foot_stance,
    hand_contacts,
    hand_rest_windows,
    swing_spans,
    walk_spans,
    walking,
)

SKEL = build_manikin("gb10000_1988", "female", 5)
REF = SourceRef("synthetic.mtask", 1, 1, 1, 2)
PROV = Provenance(("t",), REF, REF)


# -- the reference: the scans as they were before -----------------------------------------------


def foot_stance_scan(ir: MotionIR, t: np.ndarray) -> np.ndarray:
    stance = np.ones((len(t), 2), dtype=bool)
    for seg in ir.segments:
        if seg.kind not in STEPPING_KINDS:
            continue
        for step in seg.result.get("steps", ()) or ():
            k = FEET.index(str(step["foot"])[0])
            swing = (t > float(step["t_lift"]) + 1e-9) & (t < float(step["t_land"]) - 1e-9)
            stance[swing, k] = False
    return stance


def walking_scan(ir: MotionIR, t: np.ndarray) -> np.ndarray:
    mask = np.zeros(len(t), dtype=bool)
    for seg in ir.segments:
        if seg.kind == "locomotion":
            mask |= (t >= seg.start - 1e-9) & (t <= seg.end + 1e-9)
    return mask


def hand_contacts_scan(ir: MotionIR, t: np.ndarray, pose: Any = None) -> np.ndarray:
    out = np.zeros((len(t), 2), dtype=bool)
    skel = ir.skeleton
    for k, (hand, track) in enumerate(ARM_TRACKS.items()):
        segs = sorted(ir.on_track(track), key=lambda s: s.start)
        for i, seg in enumerate(segs):
            if seg.kind != "TO" or not _reachable(seg.result):
                continue
            if seg.goal.effector != hand:
                continue
            later = [s.start for s in segs[i + 1 :] if s.start >= seg.end - 1e-9]
            end = min(later, default=math.inf)
            window = (t >= seg.end - 1e-9) & (t < end - 1e-9)
            if pose is not None and skel is not None and window.any():
                if seg.goal.position is None:
                    continue
                at = site_positions(skel, pose, hand)[window]
                gap = np.linalg.norm(at - np.asarray(seg.goal.position, dtype=float), axis=-1)
                window[np.flatnonzero(window)] = gap <= SUPPORT_TOL
            out[:, k] |= window
    return out


def carried_loads_scan(ir: MotionIR) -> list[Load]:
    end_of_motion = _motion_end(ir)
    found: dict[tuple[str, float, float], Load] = {}
    grips = {side: _grips(ir, side) for side in "rl"}
    for seg in ir.segments:
        side = seg.goal.effector[:1]
        mass = float(seg.goal.params.get("load", 0.0) or 0.0)
        if side not in "rl" or seg.kind == "grip" or not mass > 0.0:
            continue
        closes = [g for g in grips[side] if g[2] and g[0] <= seg.start + EPS]
        start = closes[-1][0] if closes else seg.start
        if any(not closed and start < g0 < seg.start - EPS for g0, _, closed in grips[side]):
            start = seg.start
        opens = [g for g in grips[side] if not g[2] and g[0] >= seg.end - EPS]
        end = opens[0][1] if opens else max(end_of_motion, seg.end)
        share = mass / 2.0 if seg.goal.params.get("two_handed") else mass
        key = (side, round(start, 9), round(end, 9))
        if key not in found or found[key].mass < mass:
            found[key] = Load(side, mass, share, start, end)
    return sorted(found.values(), key=lambda x: (x.start, x.side))


# -- random timelines ---------------------------------------------------------------------------

# times on a coarse grid, so that ends meet starts and frames fall on boundaries (the ±1e-9 of
# every comparison is exercised)
TIMES = st.integers(0, 12).map(lambda k: k * 0.25)


@st.composite
def timelines(draw: st.DrawFn) -> tuple[MotionIR, np.ndarray, Any]:
    n = draw(st.integers(1, 30))
    q = np.tile(SKEL.q_comfort, (n, 1)) + draw(st.floats(-0.05, 0.05))
    pose = forward(SKEL, q, np.tile(SKEL.root_position, (n, 1)))
    hands = {h: site_positions(SKEL, pose, h) for h in ARM_TRACKS}
    segs = []
    for _ in range(draw(st.integers(0, 14))):
        kind = draw(st.sampled_from(["TO", "TA", "grip", "locomotion", "posture", "hold"]))
        side = draw(st.sampled_from("rl"))
        start = draw(TIMES)
        end = start + draw(TIMES)
        params: dict[str, Any] = {}
        result: dict[str, Any] = {}
        effector = f"{side}_hand"
        position = None
        if kind == "grip":
            params["state"] = draw(st.sampled_from(["open", "closed"]))
            track = f"{side}_hand"
        elif kind in STEPPING_KINDS:
            track = "root" if kind == "locomotion" else "body"
            result["steps"] = [
                {"foot": draw(st.sampled_from(["right", "left"])), "t_lift": a, "t_land": a + b}
                for a, b in draw(st.lists(st.tuples(TIMES, TIMES), max_size=4))
            ]
        else:
            track = f"{side}_arm"
            if draw(st.booleans()):
                effector = f"{side}_tool_x"  # a tool's tip: no rest
            result["reached"] = draw(st.booleans())
            if draw(st.integers(0, 3)):  # on its hand's place, 1 mm or 5 mm off it, or none
                k = draw(st.integers(0, n - 1))
                off = draw(st.sampled_from([0.0, 0.001, 0.005]))
                position = hands[f"{side}_hand"][k] + np.array([0.0, off, 0.0])
            if draw(st.booleans()):
                params["load"] = draw(st.sampled_from([0.0, 2.0, 9.0, 20.0]))
                params["two_handed"] = draw(st.booleans())
        goal = GoalSpec(effector, "s", position=position, params=params)
        segs.append(Segment(track, kind, start, end, goal, PROV, result=result))
    # frames on the segments' boundaries and the steps', or within 1e-9 s of them
    bounds = {0.0, *(x for seg in segs for x in (seg.start, seg.end))}
    for seg in segs:
        bounds |= {
            x for step in seg.result.get("steps", ()) for x in (step["t_lift"], step["t_land"])
        }
    t = np.array(draw(st.lists(st.sampled_from(sorted(bounds)), min_size=n, max_size=n)))
    nudge = st.sampled_from([0.0, 1e-10, -1e-10, 1e-9, -1e-9])
    t += np.array(draw(st.lists(nudge, min_size=n, max_size=n)))
    ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], segs, SKEL)
    return ir, t, pose


@settings(max_examples=300, deadline=None)
@given(timelines())
def test_stance_walking_and_rests_equal_the_scans(case: tuple[MotionIR, np.ndarray, Any]) -> None:
    ir, t, pose = case
    assert np.array_equal(foot_stance(ir, t), foot_stance_scan(ir, t))
    assert np.array_equal(foot_stance(ir, t, swing_spans(ir)), foot_stance_scan(ir, t))
    assert np.array_equal(walking(ir, t), walking_scan(ir, t))
    assert np.array_equal(walking(ir, t, walk_spans(ir)), walking_scan(ir, t))
    assert np.array_equal(hand_contacts(ir, t), hand_contacts_scan(ir, t))
    assert np.array_equal(hand_contacts(ir, t, pose), hand_contacts_scan(ir, t, pose))
    windows = hand_rest_windows(ir)
    assert np.array_equal(hand_contacts(ir, t, pose, windows), hand_contacts_scan(ir, t, pose))


@settings(max_examples=300, deadline=None)
@given(timelines())
def test_carried_loads_equal_the_scan(case: tuple[MotionIR, np.ndarray, Any]) -> None:
    ir, t, pose = case
    assert carried_loads(ir) == carried_loads_scan(ir)
    com = carried_com(ir, pose, t)
    assert np.array_equal(carried_com(ir, pose, t, held(ir)), com)
