"""`mtlc lint` rules, one test per code (MT0601–MT0606), suppressions, merging and the sweep."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.frontend import run_frontend
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.config import ConfigError, find_config, parse_config
from mtlc.lint.findings import Finding, merge
from mtlc.lint.manikins import EXTREMES, ManikinError, all_manikins, label, parse_selection
from mtlc.lint.rules import motion
from mtlc.lint.rules.view import make_view
from mtlc.lint.suppress import apply, scan
from mtlc.passes import run_motion
from mtlc.semantics import schedule

BAY = Path("tests/lint/data/bay.mtask")
PROGRAM_ONLY = LintConfig(select=frozenset({"MT0601", "MT0602", "MT0606", "MT0404"}))


def where(findings: list[Finding], code: str) -> list[tuple[int, int]]:
    return [(f.span.line, f.span.column) for f in findings if f.code == code]


@pytest.fixture(scope="module")
def bay() -> list[Finding]:
    return lint_paths([BAY], LintConfig()).findings


@pytest.fixture(scope="module")
def compiled():
    """The bay task compiled for the 5th-percentile woman (frames to tamper with)."""
    (timeline,) = run_frontend([BAY]).timelines
    return run_motion(schedule.for_manikin(timeline, EXTREMES[0]), DiagnosticSink())


def test_mt0601_unused_definition(bay: list[Finding]) -> None:
    assert where(bay, "MT0601") == [(15, 8)]
    assert "`polish`" in next(f.message for f in bay if f.code == "MT0601")


def test_mt0602_unused_parameter(bay: list[Finding]) -> None:
    assert where(bay, "MT0602") == [(11, 26)]


def test_unused_rules_skip_libraries_and_underscored_parameters(tmp_path: Path) -> None:
    lib = tmp_path / "lib.mtask"
    lib.write_text("element e(_x: Int, y: Int) {\n    still over 1 s\n}\n", encoding="utf-8")
    found = lint_paths([lib], PROGRAM_ONLY).findings
    assert [(f.code, f.span.line, f.span.column) for f in found] == [("MT0602", 1, 20)]


def test_mt0606_unused_and_unknown_suppressions(bay: list[Finding], tmp_path: Path) -> None:
    # line 19: the block's MT0605 is used (RULA fires inside the task), MT0502 hides nothing
    assert where(bay, "MT0606") == [(19, 58), (24, 42)]
    path = tmp_path / "t.mtask"
    path.write_text("task t {  # mtlc: ignore[MT9999]\n}\n", encoding="utf-8")
    (f,) = [f for f in lint_paths([path], PROGRAM_ONLY).findings if f.code == "MT0606"]
    assert (f.span.line, f.span.column) == (1, 26) and "MT9999" in f.message


def test_suppression_on_the_line_and_the_block(bay: list[Finding]) -> None:
    assert where(bay, "MT0605") == []  # the task block's suppression hides every RULA finding
    assert where(bay, "MT0501") == [(25, 5)]  # line 24's is suppressed, line 25's is not


def test_scan_ignores_hash_in_strings_and_finds_the_block_end() -> None:
    text = (
        'task t "a # not a comment" {  # mtlc: ignore[unreachable-site]\n'
        "    for x in [a] {\n"
        '        inspect(x)  # "}" mtlc: ignore[MT0501,MT0502]\n'
        "    }\n"
        "}\n"
        "# mtlc: ignore[MT0402]\n"
    )
    marks = scan("f", text)
    assert [(m.code, m.first_line, m.last_line) for m in marks] == [
        ("unreachable-site", 1, 5),
        ("MT0501", 3, 3),
        ("MT0502", 3, 3),
        ("MT0402", 6, 6),
    ]
    inside = Finding("MT0501", "m", Span("f", 4, 1, 4, 2))
    after = Finding("MT0501", "m", Span("f", 6, 1, 6, 2))
    kept = apply([inside, after], marks, report_unused=True)
    assert after in kept and inside not in kept
    assert sorted(f.span.line for f in kept if f.code == "MT0606") == [3, 3, 6]


def reverify(ir) -> None:  # type: ignore[no-untyped-def]
    """Measure the changed frames again: the rules read what verify measured."""
    from mtlc.diagnostics import DiagnosticSink
    from mtlc.passes import verify
    from mtlc.passes.context import PassContext

    verify.run(ir, PassContext(DiagnosticSink()))


def test_mt0603_joint_limit(compiled) -> None:
    ir = dataclasses.replace(compiled)
    ir.frames = dataclasses.replace(ir.frames, q=ir.frames.q.copy())
    skel = ir.skeleton
    d = skel.dof_names.index("r_elbow_flex") if "r_elbow_flex" in skel.dof_names else 0
    k = len(ir.frames.time) // 2
    ir.frames.q[k, d] = skel.upper[d] + math.radians(10)
    reverify(ir)
    view = make_view(ir, "m", LintConfig())
    found = [f for f in motion.joint_limits(view) if skel.dof_names[d] in f.message]
    assert len(found) == 1
    assert found[0].span.line == view.span(k).line
    assert "10.0°" in found[0].message and "upper" in found[0].message


def test_mt0604_ground_penetration(compiled) -> None:
    ir = dataclasses.replace(compiled)
    pos = ir.frames.root_position.copy()
    k = len(pos) // 3
    pos[k, 1] -= 0.05  # the whole body 5 cm down for one frame
    ir.frames = dataclasses.replace(ir.frames, root_position=pos)
    reverify(ir)
    before = motion.ground_penetration(make_view(compiled, "m", LintConfig()))
    view = make_view(ir, "m", LintConfig())
    after = motion.ground_penetration(view)
    new = [f for f in after if f not in before]
    assert len(new) >= 1 and any(f.span.line == view.span(k).line for f in new)
    assert any(float(f.message.rsplit(": ", 1)[1].split()[0]) >= 49 for f in new)


def test_mt0605_rula_threshold(compiled) -> None:
    strict = motion.rula(make_view(compiled, "m", LintConfig(rula_threshold=1)))
    lax = motion.rula(make_view(compiled, "m", LintConfig(rula_threshold=7)))
    assert len(strict) >= 1  # every frame scores at least 1
    assert len(lax) <= len(strict)
    assert all(f.code == "MT0605" and f.manikins == ("m",) for f in strict)


def test_merge_masks_numbers_after_the_last_colon() -> None:
    span = Span("f", 3, 5, 3, 9)
    a = Finding("MT0501", "the right hand cannot reach `s`: 40 mm short", span,
                manikins=("b",), details=("the right hand cannot reach `s`: 40 mm short",))  # fmt: skip
    b = Finding("MT0501", "the right hand cannot reach `s`: 253 mm short", span,
                manikins=("a",), details=("the right hand cannot reach `s`: 253 mm short",))  # fmt: skip
    c = Finding("MT0501", "the left hand cannot reach `s`: 40 mm short", span,
                manikins=("a",), details=("the left hand cannot reach `s`: 40 mm short",))  # fmt: skip
    merged = merge([a, b, c], ["a", "b"])
    assert len(merged) == 2
    both = next(f for f in merged if len(f.manikins) == 2)
    assert both.manikins == ("a", "b") and both.message.endswith("253 mm short")
    assert both.manikin_lines() == ["a", "b (40 mm short)"]


def test_sweep_of_all_manikins_names_each_one() -> None:
    result = lint_paths([BAY], LintConfig(select=frozenset({"MT0501"})), manikins=all_manikins())
    assert result.full == result.manikins and len(result.manikins) == 14  # all in full
    (high,) = [f for f in result.findings if f.span.line == 25]
    assert set(high.manikins) == {label(m) for m in all_manikins()}  # 2.6 m is out of reach


def test_manikin_selection() -> None:
    assert parse_selection("extremes") == EXTREMES
    assert len(parse_selection("all")) == 14
    assert parse_selection("gb10000_1988:male:p50, all")[0].percentile == 50
    for bad in ("gb10000_1988:male:3", "nobody", ""):
        with pytest.raises(ManikinError):
            parse_selection(bad)


def test_config_keys_and_lookup(tmp_path: Path) -> None:
    cfg = parse_config({"select": ["MT06", "unreachable-site"], "ignore": ["rula-score"]})
    assert cfg.enabled("MT0601") and cfg.enabled("MT0501")
    assert not cfg.enabled("MT0605") and not cfg.enabled("MT0502")
    for bad in ({"rula_threshold": 4}, {"select": ["MT99"]}, {"fail-on": "fatal"},
                {"rula-threshold": 9}):  # fmt: skip
        with pytest.raises(ConfigError):
            parse_config(bad)
    (tmp_path / "pyproject.toml").write_text("[tool.mtlc.lint]\nrula-threshold = 6\n")
    sub = tmp_path / "a" / "b"
    sub.mkdir(parents=True)
    found = find_config(sub)
    assert found is not None and found[1] == {"rula-threshold": 6}
    (sub / "mtlc.toml").write_text('[lint]\nmanikins = "all"\n')
    assert find_config(sub)[1] == {"manikins": "all"}  # the nearest wins


def test_lint_is_deterministic() -> None:
    a = lint_paths([BAY], PROGRAM_ONLY).findings
    b = lint_paths([BAY], PROGRAM_ONLY).findings
    assert a == b and [f.details for f in a] == [f.details for f in b]


def test_numeric_outputs_are_finite(bay: list[Finding]) -> None:
    numbers = [float(x) for f in bay for x in f.message.replace("`", " ").split() if _num(x)]
    assert numbers and np.isfinite(numbers).all()


def _num(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
