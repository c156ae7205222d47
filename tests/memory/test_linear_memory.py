"""The dense-frame passes keep a few hundred bytes a frame, not a pose a frame (issue 17).

Two lengths of the same standing task; the growth of the tracemalloc peak per added frame is
what the pass keeps for each frame. Before chunking: interpolate 3.2 KB, balance 9.0 KB a frame
(every frame's pose and support hull at once); with 512-frame chunks: 0.9 KB and ~15 bytes.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import balance, interpolate, run_motion
from mtlc.passes.context import PassContext


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
    n1, small = _peaks(tmp_path, 60)
    n2, large = _peaks(tmp_path, 240)
    per_frame = [(b - a) / (n2 - n1) for a, b in zip(small, large, strict=True)]
    assert per_frame[0] < 1500, per_frame  # interpolate: the frames themselves and the curves
    assert per_frame[1] < 1000, per_frame  # balance: margins and flags, not poses and hulls


def test_chunks_do_not_change_the_frames(monkeypatch: pytest.MonkeyPatch) -> None:
    """The kneeling fuel filter (balance corrects and blends frames): frames measured in chunks
    of 97 are bit for bit the frames measured all at once."""
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
