"""The keyframe IR: its JSON is complete, deterministic, and recomputable with plain numpy."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, example_ir

from mtlc.body import build_manikin, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import GoalSpec, Keyframes, Provenance, Segment, SourceRef
from mtlc.ir.serialize import round_array, to_json
from mtlc.passes import MotionOptions, lower, run_motion
from mtlc.passes.interpolate import correct_base, interpolate_naive, lowest_foot_point


def compile_ir(path: Path, **options):
    program = run_frontend([path.relative_to(ROOT)])
    (timeline,) = program.timelines
    sink = DiagnosticSink()
    return run_motion(timeline, sink, MotionOptions(**options)), sink


@pytest.fixture(scope="module")
def docs_fk() -> dict:
    """The worked example of docs/ir.md, executed as written."""
    text = (ROOT / "docs" / "ir.md").read_text(encoding="utf-8")
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    namespace: dict = {}
    exec(compile(code, "docs/ir.md", "exec"), namespace)
    return namespace


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_docs_forward_kinematics_matches_mtlc(path: Path, docs_fk: dict) -> None:
    ir = example_ir(path)
    doc = json.loads(to_json(ir))
    f = doc["frames"]
    skel = ir.skeleton
    frames = np.linspace(0, len(f["time"]) - 1, 7).astype(int)
    pose = forward(
        skel,
        np.array(f["q"])[frames],
        np.array(f["root_position"])[frames],
        np.array(f["root_rotation"])[frames],
    )
    names = ["r_hand", "l_hand", "r_heel", "l_toe", "gaze"]
    ours = site_positions(skel, pose, names)
    for row, frame in enumerate(frames):
        for k, name in enumerate(names):
            theirs = docs_fk["point"](doc, int(frame), name)
            # the JSON's rounding (0.01 mm, 1e-5 rad) moves points by up to 0.012 mm here
            assert np.allclose(theirs, ours[row, k], atol=5e-5), (name, frame)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_ir_json_is_complete_and_consistent(path: Path) -> None:
    ir = example_ir(path)
    doc = json.loads(to_json(ir))
    assert doc["format"] == "mtlc-ir" and doc["version"] == 1
    joints = doc["manikin"]["joints"]
    seen: set[str] = set()
    for j in joints:
        assert j["parent"] is None or j["parent"] in seen  # parents first
        seen.add(j["name"])
        assert j["mass"] >= 0 and len(j["offset"]) == 3 and len(j["com"]) == 3
        for dof in j["dofs"]:
            assert dof["min"] < dof["max"] and abs(np.linalg.norm(dof["axis"]) - 1) < 1e-6
    total = sum(j["mass"] for j in joints)
    assert total == pytest.approx(doc["manikin"]["mass"], rel=0.01)  # de Leva fractions sum to 1
    n_dofs = sum(len(j["dofs"]) for j in joints)
    assert n_dofs >= 34
    f = doc["frames"]
    assert len(f["dof_names"]) == n_dofs
    assert all(len(row) == n_dofs for row in f["q"])
    assert len(f["time"]) == len(f["root_position"]) == len(f["root_rotation"]) == len(f["q"])
    assert np.allclose(np.linalg.norm(f["root_rotation"], axis=1), 1, atol=1e-5)
    assert f["time"][0] == 0 and f["time"][-1] == pytest.approx(ir.duration, abs=1e-6)
    source = path.relative_to(ROOT).as_posix()
    assert doc["goals"], "every example reaches for something"
    for goal in doc["goals"]:
        assert goal["phase"] in ("TA", "TO") and goal["source"]["file"] == source
    kinds = {s["kind"] for s in doc["segments"]}
    assert kinds <= {"TA", "TO", "posture", "locomotion", "grip", "gaze", "hold"}


@pytest.mark.parametrize("path", EXAMPLES[:2], ids=lambda p: p.name)
def test_ir_json_is_byte_identical(path: Path) -> None:
    assert to_json(compile_ir(path)[0]) == to_json(example_ir(path))  # two compiles


def test_fps_sets_the_frame_rate() -> None:
    ir, _ = compile_ir(EXAMPLES[0], fps=24)
    assert ir.frames.fps == 24
    # every 1/24 s from 0, plus the end time when the duration is not a whole number of frames
    whole = int(np.floor(ir.duration * 24 + 1e-9))
    assert len(ir.frames.time) == whole + 1 + (ir.duration * 24 - whole > 1e-6)
    assert np.allclose(np.diff(ir.frames.time)[:-1], 1 / 24)
    assert ir.frames.time[-1] == pytest.approx(ir.duration)


def _squat_ir():
    """Stand, squat, stand, as keyframes: each keyframe has its feet exactly on the ground."""
    skel = build_manikin("gb10000_1988", "male", 50)
    program_dir = ROOT / "examples"
    program = run_frontend([(program_dir / "drain_hydraulic_reservoir.mtask").relative_to(ROOT)])
    ir = lower(program.timelines[0])
    ir.skeleton = skel
    ir.segments = [s for s in ir.segments if s.kind == "locomotion"]
    dofs = tuple(
        f"{side}_{name}" for side in "rl" for name in ("hip_flex", "knee_flex", "ankle_dorsi")
    )
    stand = np.zeros(len(dofs))
    squat = np.tile([1.7, 2.1, 0.35], 2)  # deep squat, heels down
    t0 = max(s.end for s in ir.segments) + 1.0
    times = np.array([t0, t0 + 1.5, t0 + 3.0])
    q = np.array([stand, squat, stand])
    heights = []
    for row in q:
        full = np.array(skel.q_comfort, dtype=float)
        for name, value in zip(dofs, row, strict=True):
            full[skel.dof_index(name)] = value
        root = np.array([0.0, 1.0, 0.45])
        pose = forward(skel, full[None], root[None])
        low = site_positions(skel, pose, ["r_heel", "r_toe", "l_heel", "l_toe"])[0, :, 1].min()
        heights.append(1.0 - (low - ir.ground))
    root = np.array([[0.0, h, 0.45] for h in heights])
    ref = SourceRef("x.mtask", 1, 1, 1, 1)
    ir.segments.append(
        Segment(
            "root",
            "posture",
            times[0],
            times[-1],
            GoalSpec("body", params={"posture": "squat"}),
            Provenance(("t",), ref, ref),
            Keyframes(time=times, dofs=dofs, q=q, root_position=root),
        )
    )
    return ir, times


def test_base_correction_keeps_a_squat_out_of_the_floor() -> None:
    ir, times = _squat_ir()
    naive = interpolate_naive(ir)
    window = (naive.time > times[0]) & (naive.time < times[-1])
    sink_depth = ir.ground - lowest_foot_point(ir, naive)[window].min()
    assert sink_depth > 0.01  # linear root height + eased angles: the feet go into the floor
    correction = correct_base(ir, naive)
    assert correction[window].max() > 0.01
    low = lowest_foot_point(ir, naive)
    # standing: the feet rest on the floor (the rest pose stands on level soles, its ankle
    # flexed by knee - hip: 0.7 mm above the hip-height root's floor, within the 2 mm a sole
    # point bears weight at)
    assert np.abs(low - ir.ground).max() < 1e-3


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_no_body_point_below_the_ground(path: Path) -> None:
    ir = example_ir(path)
    assert lowest_foot_point(ir, ir.frames).min() >= ir.ground - 1e-3


@pytest.mark.parametrize("decimals", [5, 6])
def test_round_array_is_python_round_number_for_number(decimals: int) -> None:
    """The frames are rounded a whole array at once; each number must come out as the
    ``round(x, decimals)`` (and -0.0 as 0.0) the IR JSON always wrote: the same bytes. Near
    halves (the decimal ``k.5`` at the last place and its neighbours) are where ``rint`` of a
    scaled number can pick the other side, and large, tiny and non-finite numbers."""
    rng = np.random.default_rng(7)
    scales = [rng.normal(0.0, s, 3000) for s in (1e-7, 1e-4, 1e-2, 1.0, 90.0, 1e5, 1e9, 1e13)]
    halves = np.array(
        [float(f"{k}.5e-{decimals}") for k in rng.integers(-(10**9), 10**9, 3000)]
        + [float(f"{k}5e-{decimals + 1}") for k in rng.integers(-(10**6), 10**6, 3000)]
    )
    odd = [0.0, -0.0, -1e-9, 2.5e-6, -2.5e-6, 0.000015, 1.000005, np.nan, np.inf, -np.inf, 1e300]
    x = np.concatenate(
        [*scales, halves, np.nextafter(halves, np.inf), np.nextafter(halves, -np.inf), odd]
    )
    got = round_array(x, decimals).tolist()
    want = [0.0 if round(v, decimals) == 0 else round(v, decimals) for v in x.tolist()]
    assert [repr(v) for v in got] == [repr(v) for v in want]
