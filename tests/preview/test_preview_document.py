"""The preview's data and outputs without a browser: figures, blocks, moved sites, the command."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.metrics import compute_metrics
from mtlc.preview.__main__ import main
from mtlc.preview.html import render_page, script_json
from mtlc.preview.sheet import render_sheet
from mtlc.preview.sites import run_frontend_with_sites

from .preview_support import ROOT, Example

ACCESS = Path("examples/remove_access_panel.mtask")


def test_figures_have_one_value_per_frame(examples: dict[str, Example]) -> None:
    for example in examples.values():
        n = len(example.ir.frames.time)
        figs = example.document["figures"]
        geometry = {"clearance"} if example.ir.geometry else set()
        assert set(figs) == {
            "contact_error",
            "com_margin",
            "penetration",
            "rula",
            "rula_worst_so_far",
            *geometry,
        }
        assert all(len(v) == n for v in figs.values())
        worst = np.array(figs["rula_worst_so_far"], dtype=float)
        assert np.all(np.diff(worst) >= 0) and worst.min() >= 1 and worst.max() <= 7


def test_models_are_drawn_as_read_and_the_clearance_is_the_verdict(
    examples: dict[str, Example],
) -> None:
    """The CAD examples carry their models' triangles, a part the hands hold drawn on its own
    with its placement per frame; the clearance figure is what verify measured and judged
    (``Verification.equipment_clearance``), not measured again: the smallest clearance of the
    pairs it does not excuse, a held part in the rest of the equipment minus its depth."""
    for example in examples.values():
        doc, ir = example.document, example.ir
        if not ir.geometry:
            assert "models" not in doc and "clearance" not in doc
            continue
        held = ir.verification.held_parts
        rest = [m for m in doc["models"] if not m.get("held")]
        for drawn, model in zip(rest, ir.geometry, strict=True):
            taken = np.zeros(len(model.faces), dtype=bool)
            for part in held:
                if part.model == model.name:
                    taken[part.faces] = True
            assert drawn["name"] == model.name
            assert drawn["indices"] == model.faces[~taken].ravel().tolist()
            assert np.allclose(np.reshape(drawn["positions"], (-1, 3)), model.vertices, atol=6e-5)
        parts = [m for m in doc["models"] if m.get("held")]
        assert [m["name"] for m in parts] == [p.column for p in held]
        for drawn, part in zip(parts, held, strict=True):
            assert len(drawn["placement"]) == len(ir.frames.time)
            assert np.allclose(np.reshape(drawn["placement"], (-1, 3, 4)), part.placement[:, :3],
                               atol=2e-6)  # fmt: skip
        fc = ir.verification.equipment_clearance
        judged = np.where(np.isnan(fc.clearance) | fc.excused, np.inf, fc.clearance)
        smallest = judged.reshape(len(fc.time), -1).min(axis=1)
        if fc.held:
            depth = np.nan_to_num(fc.held_depth, nan=0.0).reshape(len(fc.time), -1)
            smallest = np.minimum(smallest, np.where(depth > 0, -depth, np.inf).min(axis=1))
        figure = np.array([np.inf if v is None else v for v in doc["figures"]["clearance"]])
        assert np.allclose(figure, smallest, atol=1e-6)
        # verdicts, not distances: a hand in what it works on is excused, and not shown
        assert fc.excused.any()
        raw = np.nanmin(fc.clearance.reshape(len(fc.time), -1), axis=1)
        assert (raw < figure - 1e-6).any()
        c = doc["clearance"]
        k = int(np.argmin(smallest))
        assert c["meshes"][c["mesh"][k]] in fc.meshes
        assert c["parts"][c["part"][k]] in (*fc.capsules, *(f"held part {h}" for h in fc.held))


def test_contact_error_per_frame_agrees_with_the_metrics(examples: dict[str, Example]) -> None:
    """At each reached TO's end, the per-frame figure is the metrics' contact error."""
    example = examples["remove_access_panel"]
    figs = example.document["figures"]["contact_error"]
    t = example.ir.frames.time
    checked = 0
    for c in compute_metrics(example.ir).contact_errors:
        if not c.reachable:
            continue
        i = int(np.searchsorted(t, c.time - 1e-9))
        assert figs[i] is not None and figs[i] >= c.error - 1e-6
        checked += 1
    assert checked >= 4


def test_blocks_nest_task_action_element_with_source_lines(examples: dict[str, Example]) -> None:
    blocks = examples["remove_access_panel"].document["blocks"]
    levels = [b["level"] for b in blocks]
    assert levels.count(0) == 1
    actions = [b["label"] for b in blocks if b["level"] == 1]
    assert actions == [
        "walk_to",
        "unscrew",
        "unscrew",
        "unscrew",
        "unscrew",
        "pick",
        "walk_to",
        "place",
    ]
    task = blocks[0]
    for b in blocks[1:]:
        assert task["start"] - 1e-9 <= b["start"] <= b["end"] <= task["end"] + 1e-9
        assert b["origin"]["file"].endswith("remove_access_panel.mtask") and b["origin"]["text"]
    unscrew = next(b for b in blocks if b["label"] == "unscrew")
    assert unscrew["origin"]["text"].startswith("unscrew(right, bolt")
    # overlapping elements never share a lane
    elems = [b for b in blocks if b["level"] == 2]
    for a in elems:
        for b in elems:
            if a is not b and a["lane"] == b["lane"]:
                assert a["end"] <= b["start"] + 1e-9 or b["end"] <= a["start"] + 1e-9


def test_page_is_self_contained_and_deterministic(examples: dict[str, Example]) -> None:
    doc = examples["remove_access_panel"].document
    page = render_page(doc)
    assert page == render_page(json.loads(json.dumps(doc)))
    for needle in ("http://", "https://", "<script src", "<link "):
        assert needle not in page.replace("http://www.w3.org", "")
    assert "Copyright 2010-2026 Three.js Authors" in page and "window.mtlcPreview" in page
    assert "__DATA__" not in page and "__THREE__" not in page.split("<style>")[0]


@given(st.recursive(st.none() | st.text() | st.integers(),
                    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(), kids, max_size=4),
                    max_leaves=20))  # fmt: skip
def test_script_json_cannot_close_the_script_element(value: Any) -> None:
    text = script_json(value)
    assert "<" not in text and ">" not in text and "&" not in text
    assert json.loads(text) == value


def test_moved_site_reaches_expansion_and_the_rest_is_unchanged() -> None:
    plain = run_frontend([ACCESS], FrontendOptions())
    moved = run_frontend_with_sites(
        [ACCESS], FrontendOptions(), {"bolt_lower_left": (-0.25, 1.0, 1.1)}
    )
    a, b = plain.timelines[0], moved.timelines[0]
    sites_a = {s.name: s for s in a.sites}
    sites_b = {s.name: s for s in b.sites}
    assert sites_b["bolt_lower_left"].position == (-0.25, 1.0, 1.1)
    assert sites_b["bolt_lower_left"].span == sites_a["bolt_lower_left"].span
    for name in sites_a.keys() - {"bolt_lower_left"}:
        assert sites_a[name] == sites_b[name]
    goals = [p for p in b.primitives if p.kind == "goal" and p.params["site"] == "bolt_lower_left"]
    assert goals and all(tuple(g.params["position"]) == (-0.25, 1.0, 1.1) for g in goals)
    # a site that no scene declares changes nothing
    same = run_frontend_with_sites([ACCESS], FrontendOptions(), {"no_such_site": (0.0, 0.0, 0.0)})
    assert same.timelines[0].as_dict() == a.as_dict()


def test_command_writes_page_and_sheet(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], examples: dict[str, Example]
) -> None:
    html, png = tmp_path / "access.html", tmp_path / "access.png"
    assert main(["preview", str(ACCESS), "-o", str(html), "--png", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "wrote" in capsys.readouterr().out
    # same input, same bytes: the command's outputs equal an independent compile's
    example = examples["remove_access_panel"]
    assert html.read_text(encoding="utf-8") == render_page(example.document)
    assert png.read_bytes() == render_sheet(example.ir)


def test_command_reports_bad_input_as_a_diagnostic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.mtask"
    bad.write_text("task t {\n    walk_to((\n}\n", encoding="utf-8")
    out = tmp_path / "bad.html"
    assert main(["preview", str(bad), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "bad.mtask:2:" in err and "MT0" in err and "Traceback" not in err
    assert not out.exists()


def test_command_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["preview", str(ACCESS), "--task", "nope", "-o", str(tmp_path / "x.html")]) == 2
    assert main(["preview", str(ACCESS), "--fps", "0"]) == 2
    assert main([]) == 2


def test_sites_of_the_example_have_their_declaration_lines(examples: dict[str, Example]) -> None:
    sources = examples["remove_access_panel"].document["site_sources"]
    text = (ROOT / ACCESS).read_text(encoding="utf-8").splitlines()
    for name, ref in sources.items():
        assert name in text[ref["line"] - 1]
    assert "bolt_upper_left" in sources


TWO_TASKS = """use stdlib.actions

scene s {{
    ground 0 cm
    site button at (0, 100, 60) cm normal (0, 0, -1)
}}

task t "{title}" {{
    manikin gb10000_1988 female p50
    scene s
    press(right, button)
}}
"""


def _two_files(tmp_path: Path) -> tuple[Path, Path]:
    a, b = tmp_path / "a.mtask", tmp_path / "b.mtask"
    a.write_text(TWO_TASKS.format(title="first file"), encoding="utf-8")
    b.write_text(TWO_TASKS.format(title="second file"), encoding="utf-8")
    return a, b


def test_two_files_with_the_same_task_name_get_a_page_each(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pages were keyed by task name and named after the first file: one was lost."""
    a, b = _two_files(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["preview", str(a), str(b)]) == 0
    pages = {p.name: p.read_text(encoding="utf-8") for p in tmp_path.glob("*.html")}
    assert set(pages) == {"a.t.html", "b.t.html"}
    assert "first file" in pages["a.t.html"] and "second file" in pages["b.t.html"]


def test_an_output_name_for_several_tasks_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = _two_files(tmp_path)
    out = tmp_path / "x.html"
    assert main(["preview", str(a), str(b), "-o", str(out)]) == 2
    assert "--task" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.html"))
    assert main(["preview", str(a), str(b), "--png", str(tmp_path / "x.png")]) == 2


def test_pages_that_would_collide_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "one").mkdir()
    (tmp_path / "two").mkdir()
    first, second = tmp_path / "one" / "a.mtask", tmp_path / "two" / "a.mtask"
    first.write_text(TWO_TASKS.format(title="one"), encoding="utf-8")
    second.write_text(TWO_TASKS.format(title="two"), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["preview", str(first), str(second)]) == 2
    assert "a.t.html" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.html"))


def test_hover_text_is_the_line_the_diagnostics_count() -> None:
    """A form feed (or \\x85, \\u2028...) inside a line made ``splitlines`` count one more line,
    so the hover showed the wrong source line."""
    from types import SimpleNamespace

    from mtlc.preview.document import _ref

    text = "task t {\n    # a comment\x0cwith a form feed\u2028and more\n    press(right, b)\r\n}\n"
    ref = _ref(SimpleNamespace(file="f.mtask", line=3, column=5), {"f.mtask": text})
    assert ref["text"] == "press(right, b)"
    assert _ref(SimpleNamespace(file="f.mtask", line=9, column=1), {"f.mtask": text})["text"] == ""


def test_the_sheet_draws_the_held_part_where_the_hands_took_it(
    examples: dict[str, Example],
) -> None:
    """The contact sheet draws the models behind the poses, and the panel the hands carry
    where its placement puts it on each pose (on the bench at the end), not in the bay."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mtlc.preview.sheet import _draw_models, _model_pieces

    ir = examples["remove_access_panel_cad"].ir
    (part,) = ir.verification.held_parts
    pieces = _model_pieces(ir)
    assert [placement is part.placement for _, placement in pieces].count(True) == 1
    last = len(ir.frames.time) - 1
    fig, ax = plt.subplots()
    try:
        _draw_models(ax, pieces, last, (0, 1))
        k = next(i for i, (_, placement) in enumerate(pieces) if placement is not None)
        drawn = ax.collections[k].get_paths()[0].vertices[:3]
    finally:
        plt.close(fig)
    tri = pieces[k][0][0]
    m = part.placement[last]
    placed = tri @ m[:3, :3].T + m[:3, 3]
    assert np.allclose(drawn, placed[:, :2], atol=1e-9)
    assert np.linalg.norm(placed.mean(axis=0) - tri.mean(axis=0)) > 0.5  # on the bench
