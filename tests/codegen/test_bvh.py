"""The BVH generator, read back by an independent parser (bvhio, from PyPI).

Every joint's world position that bvhio computes from the file must match our forward
kinematics within 1 mm, on the examples (a contact frame included) and on random in-limit
poses with random root rotations (gimbal cases included); the output is byte-identical for the
same input and its numbers are formatted to a fixed width.
"""

from __future__ import annotations

import math
import re
import tempfile
from dataclasses import replace
from pathlib import Path

import bvhio
import numpy as np
import pytest
from conftest import compiled_example
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from pyglm import glm

from mtlc.body import build_manikin, forward, site_positions
from mtlc.body.skeleton import Skeleton
from mtlc.codegen.bvh import (
    CENTIMETRES_PER_METRE,
    END_SITE_BY_JOINT,
    emit_bvh,
    euler_from_matrix,
    euler_to_matrix,
)
from mtlc.frontend import run_frontend
from mtlc.ir.model import Frames, MotionIR
from mtlc.passes import run_motion

# Local, not from conftest: another conftest module under tests/ can shadow the root one.
ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))

TOLERANCE = 1e-3  # m: the read-back bound
NUMBER = re.compile(r"^-?\d+\.\d{3}$")  # 0.01 mm and 0.001 degree (docs/bvh.md)


def compile_example(path: Path) -> MotionIR:
    program = run_frontend([path])
    (timeline,) = program.timelines
    return run_motion(timeline, program.sink)


@pytest.fixture(scope="module")
def example_irs() -> dict[str, MotionIR]:
    return {p.stem: _only(compiled_example(p).motions) for p in EXAMPLES}


def _only(motions: list[MotionIR]) -> MotionIR:
    (ir,) = motions
    return ir


def read_back(text: str) -> tuple[bvhio.Joint, bvhio.BvhContainer]:
    """bvhio's joint hierarchy and its raw container for a BVH text."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "motion.bvh"
        path.write_text(text, encoding="utf-8")
        return bvhio.readAsHierarchy(str(path)), bvhio.readAsBvh(str(path))


def joint_positions(hierarchy: bvhio.Joint, names: tuple[str, ...], frame: int) -> np.ndarray:
    """(J, 3) world positions in metres, as bvhio's own hierarchy computes them."""
    hierarchy.loadPose(frame)
    by_name = {joint.Name: joint for joint, _, _ in hierarchy.layout()}
    return np.array([list(by_name[n].PositionWorld) for n in names]) / CENTIMETRES_PER_METRE


def end_site_positions(container: bvhio.BvhContainer, frame: int) -> dict[str, np.ndarray]:
    """World positions (m) of every joint and End Site, chaining bvhio's parsed local poses.

    bvhio parses the channels and turns each joint's Euler angles into a quaternion; this only
    chains those local transforms (the hierarchy drops End Sites).
    """
    out: dict[str, np.ndarray] = {}

    def walk(joint: bvhio.BvhJoint, world: glm.mat4) -> None:
        key = joint.Keyframes[frame]
        here = world * glm.translate(key.Position) * glm.mat4_cast(key.Rotation)
        out[joint.Name] = np.array(list(here * glm.vec4(0, 0, 0, 1)))[:3]
        if not joint.Children:
            out[f"{joint.Name}/end"] = np.array(list(here * glm.vec4(joint.EndSite, 1)))[:3]
        for child in joint.Children:
            walk(child, here)

    walk(container.Root, glm.mat4(1.0))
    return {k: v / CENTIMETRES_PER_METRE for k, v in out.items()}


def end_site_names(skel: Skeleton) -> dict[str, str]:
    """Leaf joint → the site its End Site stands for."""
    out = {}
    for name in skel.joint_names:
        side, _, kind = name.rpartition("_")
        if kind in END_SITE_BY_JOINT:
            out[name] = f"{side}_{END_SITE_BY_JOINT[kind]}" if side else END_SITE_BY_JOINT[kind]
    return out


def contact_frames(ir: MotionIR) -> list[int]:
    """The frames closest to each TO segment's end: the hand is on its site there."""
    assert ir.frames is not None
    ends = [s.end for s in ir.segments if s.kind == "TO"]
    return sorted({int(np.argmin(np.abs(ir.frames.time - t))) for t in ends})


def assert_read_back_matches(ir: MotionIR, frames: list[int]) -> None:
    assert ir.frames is not None
    skel = ir.skeleton
    f = ir.frames
    pose = forward(skel, f.q, f.root_position, f.root_rotation)
    hierarchy, container = read_back(emit_bvh(ir))
    ends = end_site_names(skel)
    sites = site_positions(skel, pose, list(ends.values()))
    for frame in frames:
        got = joint_positions(hierarchy, skel.joint_names, frame)
        np.testing.assert_allclose(got, pose.p[frame], rtol=0, atol=TOLERANCE)
        chained = end_site_positions(container, frame)
        for i, joint in enumerate(ends):
            np.testing.assert_allclose(
                chained[f"{joint}/end"], sites[frame, i], rtol=0, atol=TOLERANCE
            )
        chained_joints = np.array([chained[n] for n in skel.joint_names])
        np.testing.assert_allclose(chained_joints, got, rtol=0, atol=1e-5)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_examples_read_back_within_a_millimetre(path: Path, example_irs) -> None:
    ir = example_irs[path.stem]
    assert ir.frames is not None
    n = len(ir.frames.time)
    contacts = contact_frames(ir)
    assert contacts, "every example has a TO segment"
    assert_read_back_matches(ir, sorted({0, n // 3, n // 2, n - 1, *contacts}))


def test_contact_frame_hand_is_on_its_site(example_irs) -> None:
    """The contact frame the Blender check uses really has the hand at the TO goal."""
    ir = example_irs["remove_access_panel"]
    assert ir.frames is not None
    to = next(s for s in ir.segments if s.kind == "TO")
    frame = int(np.argmin(np.abs(ir.frames.time - to.end)))
    f = ir.frames
    pose = forward(ir.skeleton, f.q[frame], f.root_position[frame], f.root_rotation[frame])
    hand = site_positions(ir.skeleton, pose, to.goal.effector)
    assert to.goal.position is not None
    assert np.linalg.norm(hand - to.goal.position) < 0.01


def test_header_frames_and_numbers(example_irs) -> None:
    ir = example_irs["remove_avionics_unit"]
    assert ir.frames is not None
    text = emit_bvh(ir)
    hierarchy_part, motion_part = text.split("MOTION\n")
    lines = motion_part.splitlines()
    n = len(ir.frames.time)
    assert lines[0] == f"Frames: {n}"
    assert lines[1] == f"Frame Time: {1 / ir.frames.fps:.8f}"
    rows = lines[2:]
    assert len(rows) == n
    width = 6 + 3 * (ir.skeleton.n_joints - 1)
    for row in rows:
        values = row.split(" ")
        assert len(values) == width
        assert all(NUMBER.match(v) and v != "-0.000" for v in values)
    assert "-0.000 " not in text and "-0.000\n" not in text
    assert hierarchy_part.count("JOINT ") == ir.skeleton.n_joints - 1
    assert hierarchy_part.count("End Site") == len(end_site_names(ir.skeleton))
    assert text.endswith("\n") and "\r" not in text


def test_rest_pose_is_the_skeletons_neutral_pose(example_irs) -> None:
    """OFFSETs are our joint offsets in cm: bvhio's rest pose puts every joint where FK does."""
    ir = example_irs["drain_hydraulic_reservoir"]
    skel = ir.skeleton
    hierarchy, _ = read_back(emit_bvh(ir))
    hierarchy.loadRestPose()
    by_name = {joint.Name: joint for joint, _, _ in hierarchy.layout()}
    got = np.array([list(by_name[n].PositionWorld) for n in skel.joint_names]) / 100
    neutral = forward(skel, np.zeros(skel.n_dofs), root_position=np.zeros(3)).p
    # OFFSETs are printed to 0.01 mm: a joint 7 bones from the root may move by up to 7 halves
    np.testing.assert_allclose(got, neutral, rtol=0, atol=4e-5)


def test_channel_order_follows_each_joints_dofs(example_irs) -> None:
    ir = example_irs["drain_hydraulic_reservoir"]
    skel = ir.skeleton
    _, container = read_back(emit_bvh(ir))
    channels = {j.Name: j.Channels for j, _, _ in container.Root.layout()}
    assert channels["pelvis"] == [
        "Xposition",
        "Yposition",
        "Zposition",
        "Yrotation",
        "Xrotation",
        "Zrotation",
    ]
    for joint in skel.joints[1:]:
        letters = [c[0] for c in channels[joint.name]]
        dof_letters = ["XYZ"[int(np.argmax(np.abs(d.axis)))] for d in joint.dofs]
        assert letters[: len(dof_letters)] == dof_letters
        assert sorted(letters) == ["X", "Y", "Z"]


def test_output_is_byte_identical_for_the_same_input(example_irs) -> None:
    path = next(p for p in EXAMPLES if p.stem == "remove_avionics_unit")
    first = emit_bvh(example_irs[path.stem])
    assert emit_bvh(example_irs[path.stem]) == first
    assert emit_bvh(compile_example(path)) == first


def test_an_unfinished_ir_is_refused() -> None:
    ir = MotionIR(task="t", title=None, file="f.mtask", manikin={}, ground=0.0, sites=[])
    with pytest.raises(ValueError, match="finished IR"):
        emit_bvh(ir)


# -- properties ----------------------------------------------------------------------------
MANIKINS = [
    ("gb10000_1988", "male", 50),
    ("gb10000_1988", "female", 5),
    ("ansur2", "male", 95),
]
GIMBAL_QUATERNIONS = [
    (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0),  # pelvis pitched +90°
    (math.cos(math.pi / 4), -math.sin(math.pi / 4), 0.0, 0.0),  # pelvis pitched −90°
    (0.5, 0.5, 0.5, 0.5),  # +90° pitch after a yaw: still singular in YXZ
]


def synthetic_ir(skel: Skeleton, q: np.ndarray, root: np.ndarray, quat: np.ndarray) -> MotionIR:
    n = q.shape[0]
    frames = Frames(
        fps=30.0,
        time=np.arange(n) / 30.0,
        root_position=root,
        root_rotation=quat / np.linalg.norm(quat, axis=1, keepdims=True),
        q=q,
    )
    return MotionIR(
        task="random",
        title=None,
        file="random.mtask",
        manikin={},
        ground=0.0,
        sites=[],
        skeleton=skel,
        frames=frames,
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    manikin=st.sampled_from(MANIKINS),
    seed=st.integers(0, 2**32 - 1),
    quat=st.one_of(
        st.sampled_from(GIMBAL_QUATERNIONS),
        st.tuples(*[st.floats(-1, 1) for _ in range(4)]).filter(
            lambda v: sum(x * x for x in v) > 0.01
        ),
    ),
)
@example(manikin=MANIKINS[0], seed=0, quat=GIMBAL_QUATERNIONS[0])
def test_random_in_limit_poses_round_trip(manikin, seed: int, quat) -> None:
    """Random angles within the limits, random root: emit, parse, FK equal within 1 mm."""
    skel = build_manikin(*manikin)
    rng = np.random.default_rng(seed)
    q = skel.random_q(rng, 3)
    q[0] = skel.lower  # every limit at once, both ends
    q[1] = skel.upper
    root = rng.uniform([-5.0, 0.0, -5.0], [5.0, 2.0, 5.0], (3, 3))
    quats = np.array([quat, quat, rng.normal(size=4)])
    assert_read_back_matches(synthetic_ir(skel, q, root, quats), [0, 1, 2])


@settings(max_examples=60, deadline=None)
@given(
    order=st.permutations([0, 1, 2]),
    angles=st.tuples(
        st.floats(-math.pi, math.pi),
        st.one_of(
            st.floats(-math.pi / 2, math.pi / 2), st.sampled_from([-math.pi / 2, math.pi / 2])
        ),
        st.floats(-math.pi, math.pi),
    ),
)
def test_euler_decomposition_reproduces_the_matrix(order, angles) -> None:
    """Any rotation, gimbal-locked ones included, survives matrix → Euler → matrix."""
    order_t = (order[0], order[1], order[2])
    R = euler_to_matrix(np.array(angles), order_t)
    back = euler_to_matrix(euler_from_matrix(R, order_t), order_t)
    np.testing.assert_allclose(back, R, rtol=0, atol=1e-8)


def test_joints_about_other_axes_are_decomposed_exactly() -> None:
    """A dof about an oblique axis, or two dofs about one axis, still reads back within 1 mm."""
    base = build_manikin()
    odd_axes = {
        "r_elbow_pro": (0.0, 0.8, 0.6),
        "lumbar_lat": (1.0, 0.0, 0.0),  # lumbar then turns twice about X
        "r_knee_flex": (0.6, 0.0, 0.8),
    }
    joints = tuple(
        replace(j, dofs=tuple(replace(d, axis=odd_axes.get(d.name, d.axis)) for d in j.dofs))
        for j in base.joints
    )
    skel = Skeleton(joints=joints, sites=base.sites, dims=base.dims, comfort=base.comfort)
    q = skel.random_q(np.random.default_rng(7), 4)
    root = np.tile(skel.root_position, (4, 1))
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    text = emit_bvh(synthetic_ir(skel, q, root, quats))
    decomposed = (
        r"JOINT {}\n\s*\{{\n\s*OFFSET [^\n]*\n\s*CHANNELS 3 Yrotation Xrotation Zrotation\n"
    )
    assert re.search(decomposed.format("r_elbow"), text)
    assert re.search(decomposed.format("lumbar"), text)
    assert_read_back_matches(synthetic_ir(skel, q, root, quats), [0, 1, 2, 3])
