"""The dense-frame passes keep a few hundred bytes a frame, not a pose a frame (issue 17),
but for the one pose balance hands on to the passes after it (``FramesPosed``).

Two lengths of the same standing task; the growth of the tracemalloc peak per added frame is
what the pass keeps for each frame. Before chunking: interpolate 3.2 KB, balance 9.0 KB a frame
(every frame's pose and support hull at once); with 512-frame chunks: 0.9 KB and ~15 bytes.
"""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from mtlc.body import build_manikin, forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import Frames, GoalSpec, MotionIR, Provenance, Segment, SourceRef
from mtlc.passes import balance, interpolate, run_motion
from mtlc.passes.context import FramesPosed, PassContext


def _peaks(tmp_path: Path, seconds: int) -> tuple[int, list[int]]:
    """(dense frames, [tracemalloc peak of interpolate, of balance]) for `inspect` of seconds."""
    path = tmp_path / f"t{seconds}.mtask"
    path.write_text(
        "use stdlib.actions\nscene s {\n    site g at (0, 150, 60) cm normal (0, 0, -1)\n}\n"
        f"task t {{\n    scene s\n    inspect(g, {seconds} s)\n}}\n",
        encoding="utf-8",
    )
    (timeline,) = run_frontend([path]).timelines
    sink = DiagnosticSink()
    ctx = PassContext(sink)
    ir = run_motion(timeline, sink, until="gaze")
    peaks = []
    for motion_pass in (interpolate.run, balance.run):
        tracemalloc.start()
        try:
            ir = motion_pass(ir, ctx)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    assert ir.frames is not None
    return len(ir.frames.time), peaks


def test_interpolate_and_balance_memory_per_frame(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(balance, "CHUNK_FRAMES", 512)
    monkeypatch.setattr(interpolate, "CHUNK_FRAMES", 512)
    # the pose balance hands on (``FramesPosed``) is measured below, by itself
    monkeypatch.setattr(FramesPosed, "MAX_FRAMES", 0)
    n1, small = _peaks(tmp_path, 60)
    n2, large = _peaks(tmp_path, 240)
    per_frame = [(b - a) / (n2 - n1) for a, b in zip(small, large, strict=True)]
    assert per_frame[0] < 1500, per_frame  # interpolate: the frames themselves and the curves
    assert per_frame[1] < 1000, per_frame  # balance: margins and flags, not poses and hulls


def test_the_pose_handed_on_is_one_pose_a_frame(tmp_path: Path) -> None:
    """Balance keeps one whole-body pose of every frame for smoothing, clearance and verify
    (``FramesPosed``): the joints' frames without the dof axes and a copy of the frame, about
    2.4 KB a frame and no more (no hull, no support, no axes), up to ``MAX_FRAMES``."""
    path = tmp_path / "t.mtask"
    path.write_text(
        "use stdlib.actions\nscene s {\n    site g at (0, 150, 60) cm normal (0, 0, -1)\n}\n"
        "task t {\n    scene s\n    inspect(g, 20 s)\n}\n",
        encoding="utf-8",
    )
    (timeline,) = run_frontend([path]).timelines
    sink = DiagnosticSink()
    ctx = PassContext(sink)
    ir = run_motion(timeline, sink, until="settle")
    balance.run(ir, ctx)
    handed = ctx.cache[FramesPosed.KEY]
    arrays = [handed.q, handed.root_position, handed.root_rotation]
    arrays += [a for p in handed.poses for a in (p.R, p.p, p.axes, p.root)]
    per_frame = sum(a.nbytes for a in arrays) / len(ir.frames.time)
    assert 2000 < per_frame < 2600, per_frame
    assert FramesPosed.MAX_FRAMES * 2600 <= 150e6  # at the default motion budget


def test_chunks_do_not_change_the_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    """The kneeling fuel filter: its frames interpolated and balanced in chunks of 97 frames are
    bit for bit those computed all at once (its balance measures but corrects nothing: the
    test below covers corrections)."""
    root = Path(__file__).resolve().parents[2]
    (timeline,) = run_frontend([root / "examples" / "replace_fuel_filter.mtask"]).timelines
    runs = []
    for chunk in (1 << 30, 97):
        monkeypatch.setattr(balance, "CHUNK_FRAMES", chunk)
        monkeypatch.setattr(interpolate, "CHUNK_FRAMES", chunk)
        sink = DiagnosticSink()
        ir = run_motion(timeline, sink, until="balance")
        assert ir.frames is not None
        runs.append((ir.frames, [(d.code, d.message) for d in sink.sorted()]))
    (whole, said), (chunked, said_chunked) = runs
    assert said == said_chunked
    for name in ("time", "q", "root_position", "root_rotation"):
        assert getattr(whole, name).tobytes() == getattr(chunked, name).tobytes(), name


def test_chunks_do_not_change_a_correction(monkeypatch: pytest.MonkeyPatch) -> None:
    """A body that stands on one foot for a while, a hand held on a site: balance moves and
    blends those frames; measured in chunks of 37 frames, bit for bit the same."""
    skel = build_manikin("gb10000_1988", "male", 50)
    ref = SourceRef("synthetic.mtask", 3, 5, 3, 20)
    n = 240

    def frames() -> Frames:
        q = np.zeros((n, skel.n_dofs))
        q[:, skel.dof_index("r_shoulder_flex")] = math.radians(60)
        q[:, skel.dof_index("r_elbow_flex")] = math.radians(40)
        q[90:170, skel.dof_index("l_hip_abd")] = math.radians(20)  # on one foot for a while
        root = np.tile(skel.root_position, (n, 1))
        rot = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        return Frames(
            fps=60.0, time=np.arange(n) / 60.0, root_position=root, root_rotation=rot, q=q
        )

    first = frames()
    hand = site_positions(
        skel, forward(skel, first.q, first.root_position, first.root_rotation), "r_hand"
    )
    seg = Segment(
        "r_arm", "TO", 0.0, 0.1, GoalSpec("r_hand", "bolt", hand[0]), Provenance(("t",), ref, ref)
    )
    results = []
    for chunk in (1 << 30, 37):
        monkeypatch.setattr(balance, "CHUNK_FRAMES", chunk)
        f = frames()
        ir = MotionIR("t", None, "synthetic.mtask", {}, 0.0, [], [seg], skel)
        ir.frames = f
        _, after, failed = balance.balance_frames(ir, f)
        results.append(
            (f.q.tobytes(), f.root_position.tobytes(), after.tobytes(), failed.tobytes())
        )
        moved = np.abs(f.q - frames().q).max(axis=1) > 0
        assert moved[90:170].all() and not moved[:60].any()  # it did correct those frames
    assert results[0] == results[1]


def test_gait_and_smoothing_chunks_do_not_change_a_walk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 6 m walk with a turn: the gait's height search in chunks of 7 grid times (its feet
    visiting only the steps that set them) and smoothing in chunks of 5 frames give the same
    frames, bit for bit, as one chunk (smoothing re-pins in one batch: the solver's last bits
    depend on its batch)."""
    from mtlc.passes import locomotion, smooth

    path = tmp_path / "walk.mtask"
    path.write_text(
        "use stdlib.actions\nscene s {\n    site far at (400, 0, 450) cm\n"
        "    site g at (450, 150, 500) cm normal (0, 0, -1)\n}\n"
        "task t {\n    scene s\n    walk_to(far)\n    inspect(g)\n}\n",
        encoding="utf-8",
    )
    (timeline,) = run_frontend([path]).timelines
    runs = []
    for reach, frames in ((1 << 30, 1 << 30), (7, 5)):
        monkeypatch.setattr(locomotion, "REACH_CHUNK", reach)
        monkeypatch.setattr(smooth, "CHUNK_FRAMES", frames)
        ir = run_motion(timeline, DiagnosticSink(), until="smooth")
        assert ir.frames is not None
        runs.append((ir.frames.q.tobytes(), ir.frames.root_position.tobytes()))
    assert runs[0] == runs[1]
