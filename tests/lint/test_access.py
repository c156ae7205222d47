"""MT0610 (an opening too small for the hand) and MT0611 (the equipment hides a site), and the
geometry under them: rays against triangles and the free way through an opening."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mtlc.geometry import solids
from mtlc.geometry.load import read_mesh
from mtlc.geometry.model import SceneModel
from mtlc.geometry.openings import passage
from mtlc.geometry.rays import RayScene
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.manikins import EXTREMES

COVER = Path(__file__).parent / "data" / "cover.mtask"
CONFIG = LintConfig(select=frozenset({"MT0610", "MT0611"}), manikins="extremes")
LATCH_LINE = 16  # `press(right, latch)`


def plate(opening: tuple[str, object] | None, at=(0.0, 0.0, 0.0)) -> SceneModel:  # type: ignore[no-untyped-def]
    v, f = solids.plate((0.6, 0.45, 0.003), opening)  # type: ignore[arg-type]
    return SceneModel("cover", v + np.asarray(at), f, {}, None, None, "plate")


def through(scene: RayScene, breadth: float, thickness: float, x: float = 0.0) -> float:
    """The scale of a hand-like ellipse passing along the plate's normal at ``x``."""
    a, b = np.array([x, 0.0, -0.05]), np.array([x, 0.0, 0.10])
    return passage(scene, a, b, breadth, thickness).scale


@settings(max_examples=30, deadline=None)
@given(d=st.floats(0.03, 0.2), breadth=st.floats(0.05, 0.1))
def test_a_round_opening_lets_through_a_hand_as_broad_as_it(d: float, breadth: float) -> None:
    scene = RayScene([plate(("round", d))])
    scale = through(scene, breadth, breadth / 2)
    if math.isinf(scale):  # the rim is beyond the search radius: far wider than the hand
        assert d > 2 * breadth
    else:  # the 48-gon's inscribed circle is 0.2 % short of the true one
        assert scale == pytest.approx(d / breadth, rel=0.005)


def test_a_slot_admits_the_hand_turned_flat() -> None:
    scene = RayScene([plate(("rect", (0.10, 0.05)))])
    assert through(scene, 0.082, 0.041) >= 1.0  # 82 x 41 mm through 100 x 50 mm
    assert through(scene, 0.082, 0.055) < 1.0  # too thick for the 50 mm side
    assert through(RayScene([plate(("rect", (0.05, 0.10)))]), 0.082, 0.041) >= 1.0  # upright


def test_no_opening_is_no_verdict() -> None:
    """A wall beside the way, or the way through the plate itself: clearance and collision,
    not an opening's size."""
    scene = RayScene([plate(("round", 0.06))])
    assert math.isinf(through(scene, 0.082, 0.041, x=0.2))  # the axis crosses the plate
    beside = RayScene([plate(None, at=(0.33, 0.0, 0.0))])  # the plate's edge 3 cm from the axis
    assert math.isinf(through(beside, 0.082, 0.041))


def brute_first_hit(scene: RayScene, o: np.ndarray, d: np.ndarray) -> float:
    """The nearest crossing, one triangle at a time (the definition)."""
    best = math.inf
    for k in range(len(scene)):
        v0, e1, e2 = scene.origin[k], scene.edge1[k], scene.edge2[k]
        m = np.column_stack([-d, e1, e2])
        with np.errstate(all="ignore"):
            det = np.linalg.det(m)
        if not abs(det) >= 1e-12:
            continue
        t, u, v = np.linalg.solve(m, o - v0)
        if t > 1e-9 and u >= 0 and v >= 0 and u + v <= 1:
            best = min(best, t)
    return best


@settings(max_examples=40, deadline=None)
@given(
    o=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
    d=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
)
@example(o=(0.0, 0.0, 0.0), d=(0.75, 1.8039953427441793e-97, 0.75))  # along a seam: missed both
def test_ray_casts_agree_with_one_triangle_at_a_time(o: tuple, d: tuple) -> None:
    scene = RayScene([plate(("round", 0.12), at=(0.0, 0.0, 0.1))])
    origin, direction = np.array(o), np.array(d) / np.linalg.norm(d)
    hits = scene.cast(origin[None], direction[None], 10.0)
    expected = brute_first_hit(scene, origin, direction)
    assert hits.distance[0] == pytest.approx(expected, abs=1e-9) or (
        math.isinf(hits.distance[0]) and math.isinf(expected)
    )


def test_rays_name_the_part_of_a_model_they_meet() -> None:
    mesh = read_mesh(Path("examples/models/fuel_filter_bay.glb"))
    model = SceneModel("bay", mesh.vertices, mesh.faces, {}, None, None, None, parts=mesh.parts)
    scene = RayScene([model])
    down = scene.cast(np.array([[0.0, 1.0, 1.05]]), np.array([[0.0, -1.0, 0.0]]), 2.0)
    assert scene.name(int(down.face[0])) == "bay.shelf"  # the shelf over the filter, 0.45 m up
    assert down.distance[0] == pytest.approx(1.0 - 0.46)


def lint_cover(tmp_path: Path, diameter_cm: float, bracket: bool = False) -> list:  # type: ignore[type-arg]
    text = COVER.read_text(encoding="utf-8").replace("round 14 cm", f"round {diameter_cm:g} cm")
    if bracket:  # a plate across the line from the eyes to the latch, clear of the arm's way
        text = text.replace(
            "    site front",
            "    box bracket size (30, 14, 1) cm at (0, 137, 45) cm\n    site front",
        )
    path = tmp_path / "cover.mtask"
    path.write_text(text, encoding="utf-8")
    return lint_paths([path], CONFIG, manikins=EXTREMES).findings


def test_mt0610_a_shrunk_opening_is_reported_at_the_line(tmp_path: Path) -> None:
    assert [f for f in lint_cover(tmp_path, 14) if f.code == "MT0610"] == []
    (found,) = [f for f in lint_cover(tmp_path, 6) if f.code == "MT0610"]
    assert (found.span.line, found.span.column) == (LATCH_LINE, 5)
    assert "right hand" in found.message and "`cover`" in found.message
    assert set(found.manikins) == {"gb10000_1988:female:5", "gb10000_1988:male:95"}


def test_mt0610_opening_between_the_two_hands_breadths(tmp_path: Path) -> None:
    """7.4 cm: wider than the 5th-percentile woman's hand (70 mm), narrower than the
    95th-percentile man's (89 mm)."""
    (found,) = [f for f in lint_cover(tmp_path, 7.4) if f.code == "MT0610"]
    assert found.manikins == ("gb10000_1988:male:95",)


def test_mt0611_a_bracket_before_the_eyes_hides_the_site(tmp_path: Path) -> None:
    plain = [f for f in lint_cover(tmp_path, 20) if f.code == "MT0611"]
    hidden = [f for f in lint_cover(tmp_path, 20, bracket=True) if f.code == "MT0611"]
    assert plain == []
    assert [(f.span.line, "`bracket`" in f.message) for f in hidden] == [(LATCH_LINE + 1, True)]


def test_mt0610_on_the_access_panel_when_its_hole_shrinks(tmp_path: Path) -> None:
    """examples/remove_access_panel_cad.mtask releases a latch through the panel's 12 cm
    lightening hole: clear; with the hole made 6 cm in the CAD (make_models.py), lint reports
    it at the `press` line, for both manikins."""
    import importlib.util

    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location(
        "make_models", root / "examples/models/make_models.py"
    )
    assert spec is not None and spec.loader is not None
    make_models = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_models)
    example = root / "examples" / "remove_access_panel_cad.mtask"
    line = next(
        i for i, text in enumerate(example.read_text("utf-8").splitlines(), 1) if "press(" in text
    )
    (tmp_path / "models").mkdir()
    task = tmp_path / example.name
    task.write_text(example.read_text("utf-8"), encoding="utf-8")
    glb = tmp_path / "models" / "access_panel.glb"
    glb.write_bytes(make_models.access_panel(0.12).export(file_type="glb"))
    assert [
        f for f in lint_paths([task], CONFIG, manikins=EXTREMES).findings if f.code == "MT0610"
    ] == []
    glb.write_bytes(make_models.access_panel(0.06).export(file_type="glb"))
    (found,) = [
        f for f in lint_paths([task], CONFIG, manikins=EXTREMES).findings if f.code == "MT0610"
    ]
    assert found.span.line == line and "`panel.panel`" in found.message
    assert set(found.manikins) == {"gb10000_1988:female:5", "gb10000_1988:male:95"}
