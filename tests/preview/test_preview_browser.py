"""The preview page in a real headless Chromium: it draws, and what it draws is the IR's motion."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mtlc.body import forward, site_positions

from .preview_support import EXAMPLES, ROOT, Example

SCREENSHOT = ROOT / "docs" / "img" / "preview.png"
BACKGROUND = (0xF4, 0xF5, 0xF7)

# counts canvas pixels that differ from the page's clear colour (read back through a 2D canvas)
DRAWN_PIXELS_JS = """
const c = document.querySelector('#view canvas');
const o = document.createElement('canvas'); o.width = c.width; o.height = c.height;
const g = o.getContext('2d'); g.drawImage(c, 0, 0);
const px = g.getImageData(0, 0, o.width, o.height).data; let n = 0;
for (let i = 0; i < px.length; i += 4) {
  if (Math.abs(px[i] - arguments[0]) + Math.abs(px[i + 1] - arguments[1])
      + Math.abs(px[i + 2] - arguments[2]) > 30) n++;
}
return [n, o.width * o.height];
"""


def _open(browser: Any, example: Example) -> None:
    browser.get(example.page.as_uri())
    assert browser.execute_script("return window.mtlcPreview && window.mtlcPreview.ready")


def _contact_frame(example: Example) -> int:
    """The first frame at or after the end of the first TO the solver reached."""
    t = example.ir.frames.time
    for seg in sorted(example.ir.segments, key=lambda s: s.end):
        if seg.kind == "TO" and seg.result.get("success", True):
            return int(np.searchsorted(t, seg.end - 1e-9))
    pytest.fail(f"{example.path.name} has no reached contact")


@pytest.mark.parametrize("name", [p.stem for p in EXAMPLES])
def test_page_draws_and_matches_the_ir(
    browser: Any, examples: dict[str, Example], name: str
) -> None:
    example = examples[name]
    _open(browser, example)
    assert browser.execute_script("return window.mtlcPreview.webgl"), "WebGL did not start"
    frame = _contact_frame(example)
    browser.execute_script("window.mtlcPreview.setFrame(arguments[0])", frame)
    drawn, total = browser.execute_script(DRAWN_PIXELS_JS, *BACKGROUND)
    assert drawn > 0.05 * total, f"only {drawn} of {total} pixels drawn"
    state = browser.execute_script(
        "const p = window.mtlcPreview; return [p.frame, p.points, p.joints];"
    )
    assert state[0] == frame
    ir, f = example.ir, example.ir.frames
    pose = forward(ir.skeleton, f.q[frame], f.root_position[frame], f.root_rotation[frame])
    for hand in ("r_hand", "l_hand"):
        expected = site_positions(ir.skeleton, pose, hand)
        assert np.linalg.norm(np.array(state[1][hand]) - expected) < 1e-3, hand
    joints = np.array([state[2][n] for n in ir.skeleton.joint_names])
    assert np.abs(joints - pose.p).max() < 1e-3


def test_timeline_block_click_jumps_and_hover_shows_the_source(
    browser: Any, examples: dict[str, Example]
) -> None:
    example = examples["remove_access_panel"]
    _open(browser, example)
    blocks = browser.find_elements("css selector", ".block.level-1")
    assert len(blocks) == sum(1 for b in example.document["blocks"] if b["level"] == 1)
    target = blocks[2]
    start = float(target.get_attribute("data-start"))
    target.click()
    assert browser.execute_script("return window.mtlcPreview.time") == pytest.approx(
        start, abs=1e-6
    )
    from selenium.webdriver.common.action_chains import ActionChains

    ActionChains(browser).move_to_element(target).perform()
    tip = browser.find_element("id", "tooltip")
    assert tip.is_displayed()
    assert "remove_access_panel.mtask:" in tip.text and "unscrew(" in tip.text


def test_play_advances_time(browser: Any, examples: dict[str, Example]) -> None:
    _open(browser, examples["remove_access_panel"])
    browser.execute_script("window.mtlcPreview.setSpeed(4); window.mtlcPreview.play();")
    moved = browser.execute_async_script(
        "const done = arguments[0]; setTimeout(() => done(window.mtlcPreview.time), 400);"
    )
    browser.execute_script("window.mtlcPreview.pause()")
    assert moved > 0.0


def test_screenshot_for_the_readme(
    browser: Any, examples: dict[str, Example], request: pytest.FixtureRequest
) -> None:
    """docs/img/preview.png: written when missing or with --update-goldens (it is not a golden:
    pixels vary with the renderer)."""
    example = examples["remove_access_panel"]
    _open(browser, example)
    browser.execute_script("window.mtlcPreview.setTime(2.0)")
    png = browser.get_screenshot_as_png()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    if request.config.getoption("--update-goldens") or not SCREENSHOT.exists():
        Path(SCREENSHOT).parent.mkdir(parents=True, exist_ok=True)
        Path(SCREENSHOT).write_bytes(png)


WAIT_FOR_GENERATION_JS = """
const [want, done] = arguments;
const poll = () => {
  const p = window.mtlcPreview;
  if (p && p.generation >= want) done(p.generation); else setTimeout(poll, 50);
};
poll();
"""


def test_served_page_receives_frames_and_a_dragged_site_comes_back_recompiled(
    browser: Any, served: tuple[Any, Path]
) -> None:
    server, _ = served
    browser.get(server.url)
    assert browser.execute_async_script(WAIT_FOR_GENERATION_JS, 1) >= 1
    site, target = "bolt_upper_left", [-0.17, 1.33, 1.10]
    reply = browser.execute_async_script(
        "const [s, p, done] = arguments; window.mtlcPreview.moveSite(s, p).then(done);",
        site,
        target,
    )
    assert reply["status"] == 200 and reply["body"]["ok"] is True
    assert browser.execute_async_script(WAIT_FOR_GENERATION_JS, 2) >= 2
    hand = browser.execute_script(
        """
        const [site] = arguments, p = window.mtlcPreview, ir = p.document.ir;
        const goal = ir.goals.find((g) => g.site === site && g.phase === "TO");
        const i = ir.frames.time.findIndex((t) => t >= goal.t_end - 1e-9);
        p.setFrame(i);
        return p.points[goal.effector];
        """,
        site,
    )
    assert np.linalg.norm(np.array(hand) - target) < 1e-3
    # and the same through the mouse: press on the drawn site, drag it, release
    from selenium.webdriver.common.action_chains import ActionChains

    before = browser.execute_script(
        "return window.mtlcPreview.document.ir.scene.sites.find((s) => s.name === 'panel_front')"
        ".position"
    )
    x, y = browser.execute_script("return window.mtlcPreview.siteScreenPosition('panel_front')")
    actions = ActionChains(browser)
    pointer = actions.w3c_actions.pointer_action
    pointer.move_to_location(round(x), round(y)).pointer_down()
    pointer.move_to_location(round(x) + 30, round(y)).move_to_location(round(x) + 60, round(y))
    pointer.pointer_up()
    actions.perform()
    assert browser.execute_async_script(WAIT_FOR_GENERATION_JS, 3) >= 3
    after = browser.execute_script(
        "return window.mtlcPreview.document.ir.scene.sites.find((s) => s.name === 'panel_front')"
        ".position"
    )
    assert np.linalg.norm(np.array(after) - before) > 0.05


CAD_SCREENSHOT = ROOT / "docs" / "img" / "preview_cad.png"
# pixels of the view that change when the models are hidden (the floor is drawn under them)
MODEL_PIXELS_JS = """
const c = document.querySelector('#view canvas');
const grab = () => {
  const o = document.createElement('canvas'); o.width = c.width; o.height = c.height;
  const g = o.getContext('2d'); g.drawImage(c, 0, 0);
  return g.getImageData(0, 0, o.width, o.height).data;
};
const a = grab(); window.mtlcPreview.setModelsVisible(false);
const b = grab(); window.mtlcPreview.setModelsVisible(true);
let n = 0;
for (let i = 0; i < a.length; i += 4) {
  if (Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) + Math.abs(a[i + 2] - b[i + 2]) > 30) n++;
}
return [n, a.length / 4];
"""


def test_the_models_are_drawn_and_a_clash_is_shown(
    browser: Any, examples: dict[str, Example], request: pytest.FixtureRequest
) -> None:
    """The CAD example's panel and bench as the compile read them; at the frame of the
    smallest clearance, the model the body is inside turns red and the figure names the pair."""
    example = examples["remove_access_panel_cad"]
    doc = example.document
    _open(browser, example)
    models = browser.execute_script("return window.mtlcPreview.models")
    assert [(m["name"], m["triangles"]) for m in models] == [
        (m["name"], m["triangles"]) for m in doc["models"]
    ]
    values = np.array([np.inf if v is None else v for v in doc["figures"]["clearance"]])
    worst = int(np.argmin(values))
    browser.execute_script("window.mtlcPreview.setFrame(arguments[0])", worst)
    now = browser.execute_script("return window.mtlcPreview.clearance")
    assert now["value"] == pytest.approx(values[worst])
    drawn = browser.execute_script("return window.mtlcPreview.models")
    assert {m["name"]: m["clash"] for m in drawn}[now["mesh"]] is bool(values[worst] < 0)
    shown = browser.find_element("id", "fig-clearance").text
    assert now["part"] in shown and now["mesh"] in shown
    changed, total = browser.execute_script(MODEL_PIXELS_JS)
    assert changed > 0.005 * total, f"the models change {changed} of {total} pixels"
    png = browser.get_screenshot_as_png()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    if request.config.getoption("--update-goldens") or not CAD_SCREENSHOT.exists():
        CAD_SCREENSHOT.write_bytes(png)


def test_the_held_part_moves_with_the_hand(browser: Any, examples: dict[str, Example]) -> None:
    """The access panel the hands take out is drawn where the IR's holds put it on every
    frame (``verification.held_parts``): carried to the bench, not left in the bay."""
    example = examples["remove_access_panel_cad"]
    (part,) = example.ir.verification.held_parts
    drawn = next(m for m in example.document["models"] if m.get("held"))
    assert drawn["name"] == part.column and len(drawn["placement"]) == len(part.placement)
    vertices = np.reshape(drawn["positions"], (-1, 3))
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    where = part.placement[:, :3, :3] @ centre + part.placement[:, :3, 3]
    k = int(np.argmax(np.linalg.norm(where - centre, axis=1)))
    assert np.linalg.norm(where[k] - centre) > 0.5, "the panel is carried to the bench"
    _open(browser, example)
    for frame in (0, k):
        browser.execute_script("window.mtlcPreview.setFrame(arguments[0])", frame)
        (shown,) = browser.execute_script("return window.mtlcPreview.heldParts")
        assert shown["name"] == part.column
        assert np.linalg.norm(np.array(shown["centre"]) - where[frame]) < 1e-3, frame
    # and it is in the hands that carry it: as near to them as when they closed on it
    hold = next(h for h in part.holds if h.start - 1e-9 <= example.ir.frames.time[k] <= h.end)
    hand = browser.execute_script("return window.mtlcPreview.points")[f"{hold.side}_hand"]
    closed = int(np.searchsorted(example.ir.frames.time, hold.start - 1e-9))
    f = example.ir.frames
    pose = forward(example.ir.skeleton, f.q[closed], f.root_position[closed],
                   f.root_rotation[closed])  # fmt: skip
    grip = site_positions(example.ir.skeleton, pose, f"{hold.side}_hand")
    near = np.linalg.norm(where[closed] - grip)
    assert abs(np.linalg.norm(np.array(shown["centre"]) - hand) - near) < 0.05
