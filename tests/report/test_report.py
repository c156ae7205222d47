"""`mtlc report` end to end: the shelf example's tables (goldens), its accessibility worked
example, HTML escaping, the CSV's shape, exit codes and byte-identical output."""

from __future__ import annotations

import csv
import io
import itertools
import re
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.frontend import run_frontend
from mtlc.lint.manikins import all_manikins, parse_selection
from mtlc.report import Report, analyse_task
from mtlc.report.command import main
from mtlc.report.csvout import COLUMNS, render_csv
from mtlc.report.html import _table, render_html
from mtlc.report.tables import Table
from mtlc.report.terminal import render_terminal

SHELF = Path("tests/report/data/shelf.mtask")
RATIO = {"male": 1.0, "female": 1.0}


@pytest.fixture(scope="module")
def shelf() -> Report:
    (timeline,) = run_frontend([SHELF]).timelines
    return Report([analyse_task(timeline, all_manikins())], all_manikins(), RATIO)


def rows(report: Report) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(render_csv(report))))


@pytest.mark.parametrize(
    ("name", "render"),
    [
        ("shelf.txt", lambda r: render_terminal(r, color=False, width=200)),
        ("shelf.csv", render_csv),
        ("shelf.html", render_html),
    ],
)
def test_outputs_match_goldens(shelf: Report, golden, name: str, render) -> None:
    golden.check(f"report/{name}", render(shelf))


def test_accessibility_worked_example(shelf: Report) -> None:
    """The sweep measures the switch reached by all 14 and the shelf valve by the men from
    p90 up only; by the intervals that is 22.5 + 4.5 + 3 = 30 % of men, 0 % of women and
    (1:1) 15 % of all."""
    task = shelf.tasks[0]
    reach = {g.site: {m.label: m.reached(g) for m in task.manikins} for g in task.goals}
    assert all(reach["switch"].values())
    tall_men = {f"gb10000_1988:male:{p}" for p in (90, 95, 99)}
    assert {k for k, ok in reach["shelf_valve"].items() if ok} == tall_men
    share = {
        (r["site"], r["sex"]): float(r["value"])
        for r in rows(shelf)
        if r["section"] == "share" and r["metric"] == "share_low"
    }
    assert share["shelf_valve", "male"] == pytest.approx(0.30)
    assert share["shelf_valve", "female"] == pytest.approx(0.0)
    assert share["shelf_valve", "both"] == pytest.approx(0.15)
    assert share["switch", "both"] == pytest.approx(1.0)
    assert share["*", "both"] == pytest.approx(0.15)  # every site: the valve decides


def test_shortfalls_shrink_with_stature_within_a_sex(shelf: Report) -> None:
    task = shelf.tasks[0]
    valve = next(g for g in task.goals if g.site == "shelf_valve")
    for sex in ("male", "female"):
        by_stature = sorted(
            (m for m in task.manikins if m.spec.sex == sex), key=lambda m: m.stature
        )
        gaps = [m.distance[valve] for m in by_stature]
        assert all(a >= b - 0.005 for a, b in itertools.pairwise(gaps)), gaps


def test_every_manikin_is_compiled_in_full_with_rula(shelf: Report) -> None:
    """No manikin's numbers are a guess from a neighbour (issue 18): all 14 have RULA."""
    for m in shelf.tasks[0].manikins:
        assert m.method == "full" and m.rula is not None, m.label
        assert 1 <= m.rula.score <= 7 and m.rula.line in (16, 17, 18, 19)


def test_csv_is_one_flat_table(shelf: Report) -> None:
    table = list(csv.reader(io.StringIO(render_csv(shelf))))
    assert tuple(table[0]) == COLUMNS
    assert all(len(r) == len(COLUMNS) for r in table)
    found = {r["section"] for r in rows(shelf)}
    assert found == {"time", "manikin", "reach", "share"}
    total = next(r for r in rows(shelf) if r["section"] == "time" and r["metric"] == "total")
    assert float(total["value"]) == pytest.approx(shelf.tasks[0].time.total, abs=1e-3)


def test_title_is_escaped_in_html(shelf: Report) -> None:
    page = render_html(shelf)
    assert "Service the &lt;store&gt; &amp; check" in page
    assert "<store>" not in page


def test_a_script_in_the_title_cannot_inject_markup(tmp_path: Path) -> None:
    src = SHELF.read_text(encoding="utf-8").replace(
        '"Service the <store> & check"', '"</title><script>alert(1)</script>"'
    )
    path = tmp_path / "evil.mtask"
    path.write_text(src, encoding="utf-8")
    out = tmp_path / "r.html"
    assert main([str(path), "--manikins", "gb10000_1988:male:50", "-o", str(out)]) == 0
    page = out.read_text(encoding="utf-8")
    assert "<script" not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert page.count("</title>") == 1


TAGS = re.compile(
    r"</?(h3|table|thead|tbody|tr|th|td)( class=\"(ok|bad)\")?>|<p class=\"note\">|</p>"
)


@given(st.text(max_size=30), st.text(max_size=30), st.sampled_from(["", "ok", "bad"]))
def test_any_cell_text_is_escaped(title: str, cell: str, mark: str) -> None:
    html = _table(Table(title, (cell,), [(cell,)], cell, [(mark,)]))
    assert "<" not in TAGS.sub("", html)


def test_command_writes_html_and_csv_byte_identically(tmp_path: Path, capsys) -> None:
    outputs = []
    for run in ("a", "b"):
        html, table = tmp_path / f"{run}.html", tmp_path / f"{run}.csv"
        args = [str(SHELF), "--manikins", "extremes", "-o", str(html), "--csv", str(table)]
        assert main(args) == 0
        outputs.append((html.read_bytes(), table.read_bytes(), capsys.readouterr().out))
    assert outputs[0] == outputs[1]
    assert "Accessibility across the population" in outputs[0][2]
    # two manikins of 14: the shares are ranges (the other percentiles were not measured)
    assert "–100.0 %" in outputs[0][2]


def test_full_compiles_every_manikin() -> None:
    (timeline,) = run_frontend([SHELF]).timelines
    chosen = parse_selection("gb10000_1988:female:50,gb10000_1988:male:5,gb10000_1988:male:50")
    task = analyse_task(timeline, chosen, jobs=1)
    assert [m.method for m in task.manikins] == ["full"] * 3
    assert all(m.rula is not None for m in task.manikins)
    assert [m.label for m in task.manikins] == [
        f"{s.population}:{s.sex}:{s.percentile}" for s in chosen
    ]


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["--manikins", "nobody"], 2),
        (["--sex-ratio", "1"], 2),
        (["--sex-ratio", "0:0"], 2),
        (["--sex-ratio=-1:2"], 2),
        (["--task", "missing"], 2),
    ],
)
def test_usage_errors_exit_2(args: list[str], code: int, capsys) -> None:
    assert main([str(SHELF), *args]) == code
    assert "mtlc report:" in capsys.readouterr().err


def test_missing_file_exits_2(tmp_path: Path, capsys) -> None:
    assert main([str(tmp_path / "none.mtask")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_input_errors_exit_1_and_write_nothing(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.mtask"
    bad.write_text("task t {\n    walk_to(nowhere)\n}\n", encoding="utf-8")
    out = tmp_path / "r.html"
    assert main([str(bad), "-o", str(out)]) == 1
    assert not out.exists()
    assert "bad.mtask:2:" in capsys.readouterr().err


def test_python_m_entry_point() -> None:
    import subprocess

    done = subprocess.run(
        [sys.executable, "-m", "mtlc.report", str(SHELF), "--manikins", "nobody"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2 and "mtlc report:" in done.stderr


def test_the_prototype_table_gives_sight_and_openings(tmp_path: Path) -> None:
    """A latch behind an 8 cm opening: the 5th-percentile woman's 70 mm hand passes, the
    95th-percentile man's 89 mm does not; the terminal, CSV and HTML say the same."""
    text = Path("tests/lint/data/cover.mtask").read_text(encoding="utf-8")
    path = tmp_path / "cover.mtask"
    path.write_text(text.replace("round 14 cm", "round 8 cm"), encoding="utf-8")
    (timeline,) = run_frontend([path]).timelines
    selection = parse_selection("gb10000_1988:female:5,gb10000_1988:male:95")
    report = Report([analyse_task(timeline, selection)], selection, RATIO)
    woman, man = report.tasks[0].manikins
    (goal,) = [g for g in report.tasks[0].goals if g.site == "latch"]
    assert woman.opening[goal][0] >= woman.opening[goal][1]  # 80 mm through, 70 needed
    assert man.opening[goal][0] < man.opening[goal][1] == pytest.approx(0.089, abs=1e-3)
    assert 0.0 <= man.seen[goal] <= 1.0
    csv_rows = [r for r in rows(report) if r["section"] == "prototype"]
    assert {(r["manikin"], r["metric"]) for r in csv_rows} == {
        (m.label, metric) for m in (woman, man) for metric in ("seen", "opening")
    }
    terminal = render_terminal(report, color=False, width=200)
    assert "Sight and access openings on the prototype" in terminal
    assert "80/89" in terminal and "80/70" in terminal
    assert "Sight and access openings on the prototype" in render_html(report)
