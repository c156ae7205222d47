"""The lint view's frame → segment map in linear memory equals its dense definition."""

from __future__ import annotations

import tracemalloc
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.lint.rules.view import frame_segments, frame_segments_dense

times = st.sampled_from([0.0, 0.5, 1.0, 1.0 + 5e-10, 1.5, 2.0, 2.0 - 5e-10, 3.0, 4.5])


def _ir(bounds: list[tuple[float, float]]) -> SimpleNamespace:
    segs = [SimpleNamespace(start=min(a, b), end=max(a, b)) for a, b in bounds]
    return SimpleNamespace(segments=segs)


@settings(max_examples=300, deadline=None)
@given(
    bounds=st.lists(st.tuples(times, times), min_size=1, max_size=12),
    frames=st.lists(st.floats(-1.0, 6.0, allow_nan=False), min_size=1, max_size=40),
)
def test_equals_the_dense_definition(
    bounds: list[tuple[float, float]], frames: list[float]
) -> None:
    """Ties (equal widths, equal ends, touching ends within 1e-9) and frames before, between
    and after the segments, in and out of time order."""
    ir = _ir(bounds)
    t = np.array(frames)
    assert frame_segments(ir, t).tolist() == frame_segments_dense(ir, t).tolist()


def test_on_a_grid_of_frames() -> None:
    rng = np.random.default_rng(7)
    starts = np.sort(rng.uniform(0, 50, 300))
    ir = _ir(
        [(a, a + w) for a, w in zip(starts, rng.choice([0.0, 0.5, 1.0, 3.0], 300), strict=True)]
    )
    t = np.arange(0, 3200) / 60.0
    assert np.array_equal(frame_segments(ir, t), frame_segments_dense(ir, t))


def _peak(n_segments: int) -> int:
    """tracemalloc peak of the map for n segments of 1 s over their 60 frames each."""
    ir = _ir([(float(i), i + 1.0) for i in range(n_segments)])
    t = np.arange(n_segments * 60) / 60.0
    tracemalloc.start()
    try:
        frame_segments(ir, t)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_grows_linearly_with_the_motion() -> None:
    """8 times the motion (frames and segments) costs about 8 times the memory, not 64."""
    small, large = _peak(250), _peak(2000)
    assert large < 10 * small
    assert large < 2000 * 60 * 128  # a few words per frame; the dense mask took 2,000 per frame
