"""MT0612: the two hands on their sites at once, each on the other's side of the body.

tests/lint/data/crossed_presses.mtask presses two latches named from behind the panel (the left
hand gets the one on the manikin's right, 50 cm across), then grips a tray in both hands (one
part: the hands go across the body by construction, not a crossing). The same file with the
latches' X swapped has no finding.
"""

from __future__ import annotations

from pathlib import Path

from mtlc.lint import LintConfig, lint_paths

ROOT = Path(__file__).resolve().parents[2]
CROSSED = ROOT / "tests" / "lint" / "data" / "crossed_presses.mtask"
ONLY = LintConfig(select=frozenset({"MT0612"}), manikins=["gb10000_1988:male:50"])


def test_crossed_presses_are_one_finding_at_the_left_hands_line() -> None:
    findings = [f for f in lint_paths([CROSSED], ONLY).findings if f.code == "MT0612"]
    assert [(f.span.line, f.span.column) for f in findings] == [(20, 9)]
    (f,) = findings
    assert "`latch_left`" in f.message and "`latch_right`" in f.message
    assert "50 cm to the right" in f.message and "the arms cross" in f.message


def test_each_hand_on_its_own_side_is_no_finding(tmp_path: Path) -> None:
    text = CROSSED.read_text(encoding="utf-8")
    text = text.replace("(-25, 110", "(X, 110").replace("(25, 110", "(-25, 110")
    text = text.replace("(X, 110", "(25, 110")
    fixed = tmp_path / "uncrossed.mtask"
    fixed.write_text(text, encoding="utf-8")
    assert [f for f in lint_paths([fixed], ONLY).findings if f.code == "MT0612"] == []
