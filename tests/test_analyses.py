"""Issue 8's analyses against values worked by hand: the view cone (MT0607), the revised NIOSH
lifting equation (MT0608) and sustained RULA postures (MT0609); docs/visibility.md,
docs/lifting.md, docs/sustained.md."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin, forward
from mtlc.diagnostics import DiagnosticSink
from mtlc.ergonomics import niosh
from mtlc.ergonomics.view import eye_and_axis, outside_cone, site_view_angles, view_angle
from mtlc.frontend import run_frontend
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.config import ConfigError, parse_config
from mtlc.lint.findings import Finding
from mtlc.lint.rules.lifting import lifting_index, loaded_goals
from mtlc.lint.rules.sustained import runs_at_or_above, sustained_posture
from mtlc.lint.rules.view import MotionView, make_view
from mtlc.lint.rules.visibility import site_out_of_view
from mtlc.passes import run_motion
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

MAN = ManikinSpec("gb10000_1988", "male", 50)

LIFT_TASK = """use stdlib.actions

scene shop {
    ground 0 cm
    site floor_box at (0, 20, 45) cm
    site bench at (0, 100, 45) cm normal (0, 1, 0)
}

task heave "Lift a box from the floor onto the bench" {
    manikin gb10000_1988 male p50
    scene shop
    lift(floor_box, bench, 15 kg)
}
"""

HOLD_TASK = """use stdlib.elements

scene hangar {
    ground 0 cm
    site panel at (0, 195, 45) cm normal (0, -1, 0)
}

task hold_panel "Hold a panel overhead while it is fastened" {
    manikin gb10000_1988 male p50
    scene hangar
    reach(right, panel)
    hold(90 s)
}
"""


def _view(tmp: Path, name: str, text: str, config: LintConfig | None = None) -> MotionView:
    path = tmp / f"{name}.mtask"
    path.write_text(text, encoding="utf-8")
    program = run_frontend([path])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    ir = run_motion(schedule.for_manikin(timeline, MAN), DiagnosticSink())
    view = make_view(ir, "gb10000_1988:male:50", config or LintConfig(), timeline)
    assert view is not None
    return view


@pytest.fixture(scope="module")
def lift_view(tmp_path_factory: pytest.TempPathFactory) -> MotionView:
    return _view(tmp_path_factory.mktemp("lift"), "heave", LIFT_TASK)


@pytest.fixture(scope="module")
def hold_view(tmp_path_factory: pytest.TempPathFactory) -> MotionView:
    return _view(tmp_path_factory.mktemp("hold"), "hold_panel", HOLD_TASK)


def _with(view: MotionView, **config: object) -> MotionView:
    return dataclasses.replace(view, config=dataclasses.replace(view.config, **config))


def _lines(findings: list[Finding], code: str) -> list[int]:
    return [f.span.line for f in findings if f.code == code]


# -- visibility ---------------------------------------------------------------------------------


def test_view_angle_worked_examples() -> None:
    """Eye at the origin looking along +Z. A site 1 m ahead and 0.5 m to the side is
    atan(0.5 / 1) = 26.565° off the axis: inside a 30° cone. 1 m to the side: atan(1) = 45°,
    outside. Straight ahead: 0°; straight behind: 180°."""
    eye, ahead = np.zeros(3), np.array([0.0, 0.0, 1.0])
    sites = np.array([[0.5, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, 2.0], [0.0, 0.0, -1.0]])
    angle = np.degrees(view_angle(eye, ahead, sites))
    assert angle == pytest.approx([26.565051, 45.0, 0.0, 180.0], abs=1e-5)
    assert outside_cone(np.radians(angle), 30.0).tolist() == [False, True, False, True]
    assert outside_cone(np.radians(angle), 50.0).tolist() == [False, False, False, True]


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-3, 3), min_size=3, max_size=3),
    st.floats(0.05, 3.0),
    st.floats(0.0, math.pi),
)
def test_view_angle_is_the_angle_set_up(axis_seed: list[float], dist: float, want: float) -> None:
    """A site placed ``want`` rad off any axis, at any distance, is measured at ``want``."""
    axis = np.array(axis_seed) + np.array([0.0, 0.0, 3.5])  # never zero
    axis /= np.linalg.norm(axis)
    side = np.cross(axis, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    eye = np.array([0.3, 1.6, -0.2])
    site = eye + dist * (math.cos(want) * axis + math.sin(want) * side)
    assert float(view_angle(eye, axis, site)) == pytest.approx(want, abs=1e-6)


def test_site_view_angles_on_the_manikin() -> None:
    """The standing manikin's eye and head axis: 1 m along the axis and 0.5 m (then 1 m) to the
    side are 26.57° (then 45°) off it, whatever the eye height."""
    skel = build_manikin()
    pose = forward(skel, np.zeros(skel.n_dofs))
    eye, axis = eye_and_axis(skel, pose)
    side = np.cross(axis, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    sites = np.array([eye + axis + 0.5 * side, eye + axis + 1.0 * side])
    angles = [float(site_view_angles(skel, pose, s)) for s in sites]
    assert np.degrees(angles) == pytest.approx([26.565051, 45.0], abs=1e-4)
    assert eye[1] > 1.5  # a standing 50th-percentile man's eye is above 1.5 m


def test_mt0607_the_gaze_pass_keeps_a_high_site_in_view() -> None:
    """The bay's valve at 2.6 m: the head tilts back 70° (within the neck's 80° of extension)
    while the hand presses it, so neither extreme manikin has it outside the 30° cone."""
    found = lint_paths([Path("tests/lint/data/bay.mtask")], LintConfig()).findings
    assert [f for f in found if f.code == "MT0607"] == []


def test_mt0607_follows_the_configured_half_angle(lift_view: MotionView) -> None:
    """The lift's move to the bench is not looked at (stdlib `lift` looks at the item only)."""
    found = site_out_of_view(lift_view)
    assert _lines(found, "MT0607") == [12]
    (angle,) = re.findall(r": (\d+\.\d)° off", found[0].message)
    wider = float(angle) + 1.0
    assert site_out_of_view(_with(lift_view, view_cone_half_angle=wider)) == []
    assert len(site_out_of_view(_with(lift_view, view_cone_half_angle=float(angle) - 1))) == 1


# -- lifting: the revised NIOSH equation -------------------------------------------------------


def test_niosh_worked_example_floor_lift() -> None:
    """H = 40 cm, V = 30 cm, D = 50 cm, A = 0°, 1 lift/min for up to 1 h, good coupling:
    HM = 25/40 = 0.625; VM = 1 − 0.003·|30 − 75| = 0.865; DM = 0.82 + 4.5/50 = 0.91;
    AM = 1; FM (1/min, ≤ 1 h, V < 75) = 0.94; CM (good) = 1.00.
    RWL = 23 · 0.625 · 0.865 · 0.91 · 1 · 0.94 · 1 = 10.636 kg; a 12 kg load: LI = 1.128."""
    origin = niosh.LiftPoint(0.40, 0.30, 0.0)
    destination = niosh.LiftPoint(0.40, 0.80, 0.0)
    at_origin, _ = niosh.assess_lift(12.0, origin, destination, 1.0, "1h", "good")
    m = at_origin.multipliers
    assert (m.hm, m.vm, m.dm, m.am, m.fm, m.cm) == pytest.approx(
        (0.625, 0.865, 0.91, 1.0, 0.94, 1.0), abs=1e-9
    )
    assert at_origin.rwl == pytest.approx(10.636, abs=5e-4)
    assert at_origin.lifting_index == pytest.approx(1.128, abs=5e-4)


def test_niosh_worked_example_destination_twisted() -> None:
    """The same lift's destination, H = 30 cm, V = 80 cm, A = 30°, a one-off (0.1/min, counted
    as the 0.2 row) over up to 2 h, fair coupling: HM = 25/30 = 0.8333; VM = 1 − 0.003·5 =
    0.985; DM = 0.91 (D = 50 cm); AM = 1 − 0.0032·30 = 0.904; FM (0.2 row, ≤ 2 h, origin
    V = 30 < 75) = 0.95; CM (fair, V = 80 ≥ 75) = 1.00. RWL = 23 · 0.8333 · 0.985 · 0.91 ·
    0.904 · 0.95 · 1.00 = 14.754 kg; the origin (HM 0.625, VM 0.865, CM 0.95) is
    23 · 0.625 · 0.865 · 0.91 · 1 · 0.95 · 0.95 = 10.212 kg: the origin is the worse end."""
    origin = niosh.LiftPoint(0.40, 0.30, 0.0)
    destination = niosh.LiftPoint(0.30, 0.80, math.radians(30.0))
    a_origin, a_dest = niosh.assess_lift(10.0, origin, destination, 0.1, "2h", "fair")
    m = a_dest.multipliers
    assert (m.hm, m.vm, m.dm, m.am, m.fm, m.cm) == pytest.approx(
        (25 / 30, 0.985, 0.91, 0.904, 0.95, 1.0), abs=1e-9
    )
    assert a_dest.rwl == pytest.approx(14.754, abs=5e-4)
    assert a_origin.rwl == pytest.approx(10.212, abs=5e-4)
    assert niosh.worst((a_origin, a_dest)) is a_origin
    assert a_origin.lifting_index == pytest.approx(10.0 / 10.212, abs=1e-3)


@pytest.mark.parametrize(
    ("multiplier", "value", "expected"),
    [
        (niosh.horizontal_multiplier, 20.0, 1.0),  # H < 25 cm counts as 25
        (niosh.horizontal_multiplier, 63.0, 25 / 63),
        (niosh.horizontal_multiplier, 64.0, 0.0),
        (niosh.vertical_multiplier, 0.0, 0.775),
        (niosh.vertical_multiplier, 175.0, 0.7),
        (niosh.vertical_multiplier, 176.0, 0.0),
        (niosh.vertical_multiplier, -1.0, 0.0),
        (niosh.distance_multiplier, 10.0, 1.0),  # D < 25 cm counts as 25
        (niosh.distance_multiplier, 175.0, 0.82 + 4.5 / 175),
        (niosh.distance_multiplier, 176.0, 0.0),
        (niosh.asymmetry_multiplier, 135.0, 1 - 0.0032 * 135),
        (niosh.asymmetry_multiplier, 136.0, 0.0),
    ],
)
def test_niosh_ranges(multiplier, value: float, expected: float) -> None:  # type: ignore[no-untyped-def]
    assert multiplier(value) == pytest.approx(expected, abs=1e-12)


def test_niosh_frequency_table() -> None:
    """Rows of table 5 and linear interpolation between them (manual p.7):
    0.75/min, ≤ 1 h: halfway between 0.97 (0.5) and 0.94 (1) = 0.955;
    12.5/min, ≤ 1 h, V < 75: halfway between 0.37 and 0.00 = 0.185; V ≥ 75: (0.37+0.34)/2."""
    fm = niosh.frequency_multiplier
    assert fm(0.05, "1h", 30) == 1.0 and fm(0.2, "8h", 30) == 0.85
    assert fm(0.75, "1h", 30) == pytest.approx(0.955)
    assert fm(12.5, "1h", 30) == pytest.approx(0.185)
    assert fm(12.5, "1h", 80) == pytest.approx(0.355)
    assert fm(4, "2h", 80) == 0.72 and fm(9, "8h", 74.9) == 0.0 and fm(9, "8h", 75) == 0.15
    assert fm(15.1, "1h", 80) == 0.0
    assert niosh.coupling_multiplier("poor", 80) == 0.9
    assert niosh.coupling_multiplier("fair", 74) == 0.95
    with pytest.raises(ValueError):
        niosh.frequency_multiplier(1, "3h", 30)


def test_niosh_out_of_range_lift_has_infinite_index() -> None:
    point = niosh.LiftPoint(0.70, 0.50, 0.0)  # H 70 cm > 63: HM 0
    a, _ = niosh.assess_lift(5.0, point, point)
    assert a.rwl == 0.0 and math.isinf(a.lifting_index)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.0, 0.8),
    st.floats(-0.1, 2.0),
    st.floats(0.0, math.pi),
    st.floats(0.0, 20.0),
    st.sampled_from(niosh.DURATIONS),
    st.sampled_from(niosh.COUPLINGS),
)
def test_niosh_rwl_is_at_most_the_load_constant(
    h: float, v: float, a: float, f: float, duration: str, coupling: str
) -> None:
    point = niosh.LiftPoint(h, v, a)
    m = niosh.multipliers(point, 0.3, v, f, duration, coupling)
    values = (m.hm, m.vm, m.dm, m.am, m.fm, m.cm)
    assert all(0.0 <= x <= 1.0 for x in values)
    assert 0.0 <= m.rwl <= niosh.LOAD_CONSTANT_KG + 1e-12


def test_lift_points_geometry() -> None:
    """Ankles' midpoint at (0, 0.08, 0), feet pointing +Z, hands at (0.3, 0.8, 0.4), floor at
    0: H = hypot(0.3, 0.4) = 0.5 m; V = 0.8 m; A = atan(0.3 / 0.4) = 36.87°."""
    (p,) = niosh.lift_points(
        np.array([[0.3, 0.8, 0.4]]), np.array([[0.0, 0.08, 0.0]]), np.array([[0, 0, 0.2]]), 0.0
    )
    assert (p.horizontal, p.vertical) == pytest.approx((0.5, 0.8))
    assert math.degrees(p.asymmetry) == pytest.approx(36.869898, abs=1e-5)


def test_lift_carries_its_load_into_the_timeline(lift_view: MotionView) -> None:
    """`lift(item, onto, 15 kg)` loads the move (both hands, one lift), not the reach."""
    assert lift_view.timeline is not None
    loaded = [p for p in lift_view.timeline.primitives if p.params.get("load")]
    assert {(p.effector, p.path[-1], p.params["load"]) for p in loaded} == {
        ("left_hand", "move", 15.0),
        ("right_hand", "move", 15.0),
    }
    (lift,) = loaded_goals(lift_view)
    assert lift.load == 15.0 and lift.origin.line == 12


def test_mt0608_lifting_index_above_one(lift_view: MotionView) -> None:
    """15 kg from a box near the floor: LI above 1, at the task line, and the reported LI is
    load / (23 kg · the reported multipliers)."""
    (f,) = lifting_index(lift_view)
    assert (f.code, f.span.line) == ("MT0608", 12)
    li = float(re.search(r"LI (\d+\.\d+)", f.message)[1])  # type: ignore[index]
    rwl = float(re.search(r"RWL (\d+\.\d+) kg", f.message)[1])  # type: ignore[index]
    names = ("HM", "VM", "DM", "AM", "FM", "CM")
    mult = [float(re.search(rf"{n} (\d\.\d\d)", f.message)[1]) for n in names]  # type: ignore[index]
    assert li > 1.0 and li == pytest.approx(15.0 / rwl, rel=0.01)  # RWL printed to 0.1 kg
    assert rwl == pytest.approx(23.0 * math.prod(mult), rel=0.02)
    worst = niosh.worst(_assess(lift_view))  # origin or destination: whichever scores worse
    fair = 0.95 if worst.point.vertical < 0.75 else 1.0  # fair coupling, by V (table 7)
    assert mult[-1] == fair


def test_mt0608_light_load_and_configuration(lift_view: MotionView) -> None:
    (origin, destination) = _assess(lift_view)
    worst = niosh.worst((origin, destination))
    assert 1.0 < worst.lifting_index < 3.0
    assert origin.point.vertical < destination.point.vertical  # from low to the bench
    light = _with_load(lift_view, worst.rwl * 0.99)
    assert lifting_index(light) == []
    good = _with(lift_view, lift_coupling="good")
    assert "CM 1.00" in lifting_index(good)[0].message
    frequent = _with(lift_view, lift_frequency=12.0)  # table 5: V < 75, ≤ 1 h
    assert "FM 0.37" in lifting_index(frequent)[0].message
    too_often = _with(lift_view, lift_frequency=13.0)  # beyond the table for V < 75: FM 0
    assert "LI inf, RWL 0.0 kg" in lifting_index(too_often)[0].message


def _assess(view: MotionView) -> tuple[niosh.LiftAssessment, niosh.LiftAssessment]:
    from mtlc.lint.rules.lifting import assess

    (lift,) = loaded_goals(view)
    return assess(view, lift)


def _with_load(view: MotionView, load: float) -> MotionView:
    assert view.timeline is not None
    prims = [
        dataclasses.replace(p, params={**p.params, "load": load}) if "load" in p.params else p
        for p in view.timeline.primitives
    ]
    return dataclasses.replace(view, timeline=dataclasses.replace(view.timeline, primitives=prims))


# -- sustained postures -------------------------------------------------------------------------


def test_runs_at_or_above_worked_example() -> None:
    """At 10 frames/s: 700 frames at 5 (70 s > 60: reported), 5 frames at 4, 601 frames at 5–6
    (60.1 s: reported, worst 6), 3 frames at 2, 600 frames at 7 (exactly 60 s: not longer, not
    reported)."""
    grand = np.array([3] * 10 + [5] * 700 + [4] * 5 + [5] * 300 + [6] * 301 + [2] * 3 + [7] * 600)
    runs = runs_at_or_above(grand, 5, 10.0, 60.0)
    assert [(r.start, r.stop, r.worst) for r in runs] == [(10, 710, 5), (715, 1316, 6)]
    assert [r.seconds for r in runs] == pytest.approx([70.0, 60.1])
    assert runs_at_or_above(grand, 7, 10.0, 59.9)[0].seconds == pytest.approx(60.0)
    assert runs_at_or_above(grand, 8, 10.0, 0.0) == []


def test_mt0609_held_overhead_reach(hold_view: MotionView) -> None:
    """An overhead reach held for 90 s: one run, at the reach's line, lasting the hold plus the
    part of the reach that scores 5 or more (between 90 and 92 s)."""
    (f,) = sustained_posture(hold_view)
    assert (f.code, f.span.line) == ("MT0609", 11)
    seconds = float(re.search(r": (\d+\.\d) s,", f.message)[1])  # type: ignore[index]
    assert 90.0 <= seconds <= 92.0
    assert sustained_posture(_with(hold_view, sustained_seconds=seconds + 0.1)) == []
    (at_seven,) = sustained_posture(_with(hold_view, sustained_rula=7))
    shorter = float(re.search(r": (\d+\.\d) s,", at_seven.message)[1])  # type: ignore[index]
    assert 60.0 < shorter <= seconds and "RULA 7 or more" in at_seven.message


# -- configuration ------------------------------------------------------------------------------


def test_analysis_configuration_keys() -> None:
    cfg = parse_config(
        {
            "view-cone-half-angle": 40,
            "sustained-rula": 6,
            "sustained-seconds": 30,
            "lift-frequency": 2,
            "lift-duration": "8h",
            "lift-coupling": "poor",
        }
    )
    assert (cfg.view_cone_half_angle, cfg.sustained_rula, cfg.sustained_seconds) == (40, 6, 30)
    assert (cfg.lift_frequency, cfg.lift_duration, cfg.lift_coupling) == (2, "8h", "poor")
    default = LintConfig()
    assert (default.view_cone_half_angle, default.sustained_rula) == (30.0, 5)
    assert (default.sustained_seconds, default.lift_frequency) == (60.0, 0.2)
    assert (default.lift_duration, default.lift_coupling) == ("1h", "fair")
    for bad in ({"lift-coupling": "great"}, {"lift-duration": 1}, {"sustained-rula": 9}):
        with pytest.raises(ConfigError):
            parse_config(bad)


# -- the preview's view cone -------------------------------------------------------------------


def test_preview_document_carries_the_half_angle(lift_view: MotionView) -> None:
    from mtlc.preview.document import preview_document

    assert preview_document(lift_view.ir, {})["view_cone"] == {"half_angle_deg": 30.0}
    doc = preview_document(lift_view.ir, {}, view_cone_half_angle=20)
    assert doc["view_cone"] == {"half_angle_deg": 20.0}


@pytest.fixture(scope="module")
def chromium():  # type: ignore[no-untyped-def]
    """A headless Chromium (as tests/preview uses), or skip when it is not installed."""
    from preview.preview_support import (
        CHROMEDRIVER,
        CHROMIUM,
        CHROMIUM_MISSING,
        SELENIUM_MISSING,
        headless_chromium,
    )

    pytest.importorskip("selenium.webdriver", reason=SELENIUM_MISSING)
    if not CHROMIUM.exists() or not CHROMEDRIVER.exists():
        pytest.skip(CHROMIUM_MISSING)
    with headless_chromium() as driver:
        yield driver


def test_preview_draws_the_view_cone_from_the_eye(
    lift_view: MotionView, chromium, tmp_path: Path
) -> None:  # type: ignore[no-untyped-def]
    """The page's cone starts at the eye and points along the head's axis, as Python computes
    them for the same frame; it has the document's half-angle and toggles off and on."""
    from mtlc.preview.document import preview_document
    from mtlc.preview.html import render_page

    page = tmp_path / "heave.html"
    doc = preview_document(lift_view.ir, {}, view_cone_half_angle=25)
    page.write_text(render_page(doc), encoding="utf-8")
    chromium.get(page.as_uri())
    frame = len(lift_view.time) // 2
    chromium.execute_script("window.mtlcPreview.setFrame(arguments[0])", frame)
    cone = chromium.execute_script("return window.mtlcPreview.viewCone")
    assert cone["halfAngle"] == 25 and cone["visible"] is True
    pose = forward(lift_view.ir.skeleton, lift_view.q[frame], *_root(lift_view, frame))
    eye, axis = eye_and_axis(lift_view.ir.skeleton, pose)
    assert np.allclose(cone["apex"], eye, atol=1e-5)
    assert np.allclose(cone["axis"], axis, atol=1e-5)
    chromium.find_element("id", "view-cone").click()
    assert chromium.execute_script("return window.mtlcPreview.viewCone.visible") is False
    chromium.execute_script("window.mtlcPreview.setViewCone(true)")
    assert chromium.execute_script("return document.getElementById('view-cone').checked")


def _root(view: MotionView, frame: int) -> tuple[np.ndarray, np.ndarray]:
    assert view.ir.frames is not None
    return view.ir.frames.root_position[frame], view.ir.frames.root_rotation[frame]
