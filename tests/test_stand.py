"""Where a walk to a site stops (``semantics.stand``): on a floor spot, 0.35 m in front of a site
above the floor; and what that does for a carry onto a raised site, on the frames."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import compile_on
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mtlc.frontend import run_frontend
from mtlc.semantics.stand import FLOOR_SPOT, WORK_DISTANCE, stand_point

coord = st.floats(-50.0, 50.0, allow_nan=False)
height = st.floats(0.0, 3.0, allow_nan=False)
normal = st.one_of(
    st.none(),
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
        lambda n: math.hypot(*n) > 0.1
    ),
)


@settings(max_examples=300, deadline=None)
@given(coord, height, coord, normal, coord, coord, st.floats(-1.0, 1.0))
@example(0.0, 0.05, 0.0, None, 0.0, 0.0, 1.0)  # 1.05 - 1.0 > 0.05 in floating point
def test_a_raised_site_is_stood_in_front_of_and_a_floor_spot_on(
    x: float, h: float, z: float, n: tuple[float, float, float] | None, sx: float, sz: float,
    ground: float,
) -> None:  # fmt: skip
    site = (x, ground + h, z)
    stand, in_front = stand_point(site, n, (sx, ground, sz), ground)
    assert stand[1] == ground
    across = math.hypot(stand[0] - x, stand[2] - z)
    if h <= FLOOR_SPOT:
        assert not in_front and across == 0.0
        return
    assert in_front
    assert math.isclose(across, WORK_DISTANCE, rel_tol=1e-9)
    if n is not None and math.hypot(n[0], n[2]) >= 0.5 * math.hypot(*n):
        # along the normal's horizontal part
        flat = np.array([n[0], n[2]]) / math.hypot(n[0], n[2])
        way = np.array([stand[0] - x, stand[2] - z]) / across
        assert np.allclose(way, flat, atol=1e-9)
    elif math.hypot(sx - x, sz - z) > 1e-6:
        # on the side the walk comes from: from the site toward the start
        toward = np.array([sx - x, sz - z]) / math.hypot(sx - x, sz - z)
        way = np.array([stand[0] - x, stand[2] - z]) / across
        assert np.allclose(way, toward, atol=1e-9)


CARRY = """\
use stdlib.actions
use stdlib.elements
scene s {
    site bench_top at (2, 0.9, 3) m normal (0, 1, 0)
    site panel_bolt at (-1, 1.2, 2) m normal (0, 0, -1)
    site spot at (1, 0, 1) m
}
task t {
    manikin gb10000_1988 female p50
    scene s
    carry(left, bench_top)
    walk_to(panel_bolt)
    walk_to(spot)
}
"""


def test_walks_stop_in_front_of_raised_sites_and_face_them(tmp_path: Path) -> None:
    path = tmp_path / "t.mtask"
    path.write_text(CARRY, encoding="utf-8")
    program = run_frontend([path])
    assert program.diagnostics == []
    (timeline,) = program.timelines
    walks = [p for p in timeline.primitives if p.kind == "locomotion"]
    ends = [tuple(w.params["to"]) for w in walks]
    # the bench top from the start's side, 0.35 m short of it
    way = np.array([2.0, 3.0]) / math.hypot(2.0, 3.0)
    assert np.allclose([ends[0][0], ends[0][2]], np.array([2.0, 3.0]) - WORK_DISTANCE * way)
    assert walks[0].params["facing"] == "bench_top"
    # the bolt along its normal, on its -Z side; the floor spot stood on, facing its own way
    assert np.allclose(ends[1], (-1.0, 0.0, 2.0 - WORK_DISTANCE))
    assert walks[1].params["facing"] == "panel_bolt"
    assert ends[2] == (1.0, 0.0, 1.0) and walks[2].params["facing"] is None


@pytest.mark.parametrize("manikin", [("female", 5), ("male", 95)], ids=["F5", "M95"])
def test_a_carry_onto_a_raised_site_keeps_the_hand_out_of_the_body(
    tmp_path: Path, manikin: tuple[str, int]
) -> None:
    """Walked onto its footprint, the site 1 m up was inside the trunk: the hand went 118 mm
    into it (MT0514) and stayed there through the next walk (20 m of it)."""
    path = tmp_path / "c.mtask"
    path.write_text(
        "use stdlib.actions\nuse stdlib.elements\n"
        "scene s {\n    site top at (0.5, 1, 4) m\n    site back at (0, 0, 0) m\n}\n"
        "task c {\n    manikin gb10000_1988 male p50\n    scene s\n"
        "    carry(left, top)\n    walk_to(back)\n}\n",
        encoding="utf-8",
    )
    ir, sink = compile_on(path, manikin)
    assert [d.code for d in sink.items if d.code == "MT0514"] == []
    fr = ir.frames
    assert fr is not None
    (to,) = [s for s in ir.segments if s.kind == "TO"]
    i = int(np.searchsorted(fr.time, to.end - 1e-9))
    root = fr.root_position[i]
    assert math.isclose(math.hypot(root[0] - 0.5, root[2] - 4.0), WORK_DISTANCE, abs_tol=0.03)
    assert to.result["distance"] <= 0.005
