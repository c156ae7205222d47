"""Unicode names: read by the XID rules in NFC form, one diagnostic per bad word, and a Chinese
procedure through check, fmt, lint, compile and report, with the motion of its ASCII twin."""

from __future__ import annotations

import ast as pyast
import json
import unicodedata
from pathlib import Path

from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.cli import main
from mtlc.diagnostics import DiagnosticSink
from mtlc.fmt import format_source
from mtlc.frontend import run_frontend
from mtlc.syntax.lexer import _scan, comments, tokenize

ZH = ROOT / "tests" / "data" / "zh_replace_filter.mtask"
# every name of the Chinese procedure -> its name in examples/replace_fuel_filter.mtask
TWIN = {
    "发电机滑橇": "generator_skid",
    "滑橇前方": "skid_front",
    "滤杯": "filter_bowl",
    "接油盘": "drain_tray",
    "备件箱": "spares_box",
    "拧下": "spin_off",
    "手": "hand",
    "零件": "part",
    "圈数": "turns",
    "更换燃油滤芯": "replace_fuel_filter",
}


def _codes(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "main.mtask"
    path.write_text(text, encoding="utf-8")
    return [d.code for d in run_frontend([path]).diagnostics]


def _ascii_twin(text: str) -> str:
    for zh in sorted(TWIN, key=len, reverse=True):
        text = text.replace(zh, TWIN[zh])
    return text


SCENE = "use stdlib.actions\n\nscene 机舱 {\n    site 螺栓_1 at (0, 120, 60) cm\n}\n\n"


def test_chinese_names_check_clean(tmp_path: Path) -> None:
    text = (
        SCENE + 'task 拆卸 "拆卸面板" {\n    scene 机舱\n    unscrew(right, 螺栓_1, turns: 1)\n}\n'
    )
    assert _codes(tmp_path, text) == []


def test_two_spellings_of_one_name_are_one_name(tmp_path: Path) -> None:
    composed, decomposed = "caf\u00e9", "cafe\u0301"
    assert unicodedata.normalize("NFC", decomposed) == composed
    text = (
        f"use stdlib.actions\nscene s {{\n    site {composed} at (0, 120, 60) cm\n}}\n"
        f"task t {{\n    scene s\n    walk_to({decomposed})\n}}\n"
    )
    assert _codes(tmp_path, text) == []
    twice = text.replace("}\ntask", f"    site {decomposed} at (0, 1, 0) m\n}}\ntask", 1)
    assert _codes(tmp_path, twice) == ["MT0202"]  # one name defined twice


def test_one_diagnostic_per_bad_word(tmp_path: Path) -> None:
    text = SCENE + "task t {\n    scene 机舱\n    unscrew(right, 螺栓①, turns: 1)\n}\n"
    path = tmp_path / "main.mtask"
    path.write_text(text, encoding="utf-8")
    (diag,) = run_frontend([path]).diagnostics
    assert diag.code == "MT0108" and "U+2460 CIRCLED DIGIT ONE" in (diag.help or "")
    assert (diag.span.line, diag.span.column, diag.span.end_column) == (9, 20, 23)


def test_full_width_punctuation_is_one_diagnostic_each_and_read_as_ascii(tmp_path: Path) -> None:
    text = SCENE + "task t {\n    scene 机舱\n    unscrew（right，螺栓_1, turns: 1)\n}\n"
    assert _codes(tmp_path, text) == ["MT0102", "MT0102"]
    assert _codes(tmp_path, text.replace("1)", "1)\u3000")) == ["MT0102"] * 3


def test_missing_scene_in_chinese_is_still_found(tmp_path: Path) -> None:
    text = SCENE + "task t {\n    unscrew(right, 螺栓_2, turns: 1)\n}\n"
    assert _codes(tmp_path, text) == ["MT0201"]


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=40))
def test_scan_covers_every_character_once(text: str) -> None:
    pos = 0
    for _kind, start, end in _scan(text):
        assert start == pos and end > start
        pos = end
    assert pos == len(text)


@settings(max_examples=200, deadline=None)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=12))
def test_a_word_is_a_name_or_one_diagnostic(word: str) -> None:
    """Whatever a single word holds, it never gives more than one diagnostic per lexeme."""
    sink = DiagnosticSink()
    tokens = tokenize(f"task {word} {{\n}}\n", "x.mtask", sink)
    lexemes = [k for k, _, _ in _scan(word) if k not in ("WS", "NL", "COMMENT")]
    assert len(sink.items) <= max(1, len(lexemes))
    if word.isidentifier() and word.isascii() is False and unicodedata.is_normalized("NFC", word):
        assert sink.items == [] and tokens[1].value == word


def test_comments_are_found_after_unicode_names() -> None:
    text = 'scene 机舱 { # 注释 #1\n    site 螺栓_1 at (0, 1, 0) m # "x\n}\n'
    assert [c.value for c in comments(text)] == ["# 注释 #1", '# "x']


def test_chinese_procedure_formats_to_itself() -> None:
    text = ZH.read_text(encoding="utf-8")
    assert format_source(text, str(ZH)).text == text  # canonical already, every name kept
    messy = text.replace("    site 滤杯 at", "  site   滤杯    at").replace(
        "拧下(right,", "拧下( right ,"
    )
    once = format_source(messy, str(ZH)).text
    assert once == text and format_source(once, str(ZH)).text == once


def test_fmt_keeps_a_decomposed_name_stable() -> None:
    text = "scene s {\n    site cafe\u0301 at (0, 1, 0) m\n}\n"
    once = format_source(text, "x.mtask").text
    assert once is not None and unicodedata.normalize("NFC", once) == unicodedata.normalize(
        "NFC", text
    )
    assert format_source(once, "x.mtask").text == once


def test_chinese_procedure_compiles_to_the_motion_of_its_ascii_twin(tmp_path: Path) -> None:
    zh_dir, en_dir = tmp_path / "zh", tmp_path / "en"
    for d, text in ((zh_dir, ZH.read_text(encoding="utf-8")), (en_dir, None)):
        d.mkdir()
        (d / "p.mtask").write_text(
            text if text is not None else _ascii_twin(ZH.read_text(encoding="utf-8")),
            encoding="utf-8",
        )
    for d in (zh_dir, en_dir):
        argv = ["compile", str(d / "p.mtask"), "-o", str(d / "out"), "--target", "all"]
        assert main([*argv, "--fps", "10", "--source-map"]) == 0
    zh_out = {p.name: p for p in (zh_dir / "out").iterdir()}
    en_out = {p.name: p for p in (en_dir / "out").iterdir()}
    assert len(zh_out) == len(en_out) == 4
    zh_bvh = next(p for n, p in zh_out.items() if n.endswith(".bvh"))
    en_bvh = next(p for n, p in en_out.items() if n.endswith(".bvh"))
    assert zh_bvh.read_bytes() == en_bvh.read_bytes()  # joint names and motion do not move

    zh_ir = next(p for n, p in zh_out.items() if n.endswith(".ir.json")).read_text("utf-8")
    en_ir = next(p for n, p in en_out.items() if n.endswith(".ir.json")).read_text("utf-8")
    assert "更换燃油滤芯" in zh_ir and "滤杯" in zh_ir  # the IR keeps the names as written
    assert json.loads(_ascii_twin(zh_ir).replace("/zh/", "/en/")) == json.loads(en_ir)

    script = (zh_dir / "out" / "p.py").read_text(encoding="ascii")  # ASCII only
    tree = pyast.parse(script)
    (func,) = [n for n in tree.body if isinstance(n, pyast.FunctionDef)]
    assert func.name.isascii() and func.name.isidentifier()
    assert pyast.get_docstring(func) == "更换燃油滤芯 FF-3"  # the title, escaped safely
    source_map = json.loads((zh_dir / "out" / "p.py.map.json").read_text("utf-8"))
    assert source_map["functions"] == {func.name: "更换燃油滤芯"}


def test_chinese_procedure_lints_and_reports(tmp_path: Path, capsys) -> None:
    rel = ZH.relative_to(ROOT).as_posix()
    one = ["--manikins", "gb10000_1988:female:5"]  # one manikin keeps the test to seconds
    assert main(["lint", rel, "--format", "json", *one]) in (0, 1)
    findings = json.loads(capsys.readouterr().out)
    text = json.dumps(findings, ensure_ascii=False)
    assert "更换燃油滤芯" in text
    assert not any(c in text for c in ('"MT01', '"MT02', '"MT03'))  # only motion findings
    csv = tmp_path / "r.csv"
    assert main(["report", rel, *one, "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    assert "更换燃油滤芯" in out and "滤杯" in csv.read_text(encoding="utf-8")


# -- help lines ------------------------------------------------------------------------------


def _diagnostics(tmp_path: Path, text: str):
    path = tmp_path / "main.mtask"
    path.write_text(text, encoding="utf-8")
    return run_frontend([path]).diagnostics


BAY = "use stdlib.actions\n\nscene bay {\n    site a at (0, 120, 60) cm\n}\n\n"


def test_a_missing_stdlib_use_is_named(tmp_path: Path) -> None:
    text = BAY + "task t {\n    scene bay\n    tool wrench_10mm\n    walk_to(a)\n}\n"
    (diag,) = _diagnostics(tmp_path, text)
    assert diag.code == "MT0201" and "add `use stdlib.tools`" in (diag.help or "")


def test_unit_suggestions_stay_in_the_expected_dimension(tmp_path: Path) -> None:
    text = BAY.replace("60) cm", "60) cms") + "task t {\n    scene bay\n    inspect(a, 3 cms)\n}\n"
    helps = [d.help for d in _diagnostics(tmp_path, text)]
    assert helps == ["did you mean `cm`?", "did you mean `ms`?"]  # a Length, then a Duration
    text = BAY + "task t {\n    scene bay\n    inspect(a, 3 s * (1 cms / 1 cm))\n}\n"
    assert "`cm` or `ms`" in (_diagnostics(tmp_path, text)[0].help or "")  # no context: both


def test_a_missing_comma_is_pointed_at(tmp_path: Path) -> None:
    for call, column, between in [
        ("unscrew(right a, turns: 1)", 18, "arguments"),
        ("unscrew(right, a, turns: 1 load: 2 kg)", 31, "arguments"),
        ("inspect(a, (1 s 2 s))", 20, "items"),
    ]:
        text = BAY + f"task t {{\n    scene bay\n    {call}\n}}\n"
        (diag,) = _diagnostics(tmp_path, text)
        assert diag.message == f"expected `,` between {between}", call
        assert (diag.span.line, diag.span.column) == (9, column), call


def test_function_names_escape_without_ambiguity() -> None:
    from mtlc.codegen.jackscript import function_name

    assert function_name("拆卸", set()) == "_u62c6_u5378"
    assert function_name("\u10000", set()) != function_name("\U00010000", set())
