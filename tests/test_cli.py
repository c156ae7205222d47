"""The command line: exit codes, formats, explain, atomic outputs, colour."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, example_ir

from mtlc.cli import main
from mtlc.diagnostics import CODES

FLAGSHIP = "examples/remove_access_panel.mtask"


def run(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "mtlc", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        timeout=120,
    )


def test_check_clean_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", FLAGSHIP]) == 0
    assert "ok: 1 file, 1 task" in capsys.readouterr().err


def test_check_errors_exit_1_with_rustc_style_text(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.mtask"
    bad.write_text("use stdlib.actions\ntask t {\n    walk_too(x)\n}\n")
    assert main(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "error[MT0201]: unknown name `walk_too`" in err
    assert f"--> {bad.as_posix()}:3:5" in err
    assert "  |     ^^^^^^^^" in err
    assert "= help: did you mean `walk_to`?" in err
    assert "\x1b[" not in err  # NO_COLOR is set by conftest


def test_usage_errors_exit_2() -> None:
    assert run("check").returncode == 2
    assert run("nonsense").returncode == 2
    assert run("check", FLAGSHIP, "--manikin", "gb10000_1988:female:3").returncode == 2
    assert run("check", FLAGSHIP, "--expansion-budget", "0").returncode == 2
    assert run().returncode == 2


def test_python_dash_m_and_version() -> None:
    out = run("--version")
    assert out.returncode == 0 and out.stdout.startswith("mtlc ")


def test_json_format_is_versioned(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.mtask"
    bad.write_text("task t {\n    walk_too()\n}\n")
    assert main(["check", "--format", "json", str(bad)]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["format"] == "mtlc-diagnostics" and doc["version"] == 1
    (d,) = doc["diagnostics"]
    assert d["code"] == "MT0201" and d["severity"] == "error"
    assert (d["span"]["line"], d["span"]["column"], d["span"]["end_column"]) == (2, 5, 13)
    assert doc["summary"] == {"errors": 1, "warnings": 0}


def test_color_only_when_forced_and_no_color_unset() -> None:
    env = {"PATH": "/usr/bin:/bin", "FORCE_COLOR": "1"}
    out = run("check", str(ROOT / "tests" / "data" / "unknown_name.mtask"), env=env)
    assert "\x1b[" in out.stderr
    env["NO_COLOR"] = "1"
    out = run("check", str(ROOT / "tests" / "data" / "unknown_name.mtask"), env=env)
    assert "\x1b[" not in out.stderr and "error[MT0201]" in out.stderr


@pytest.mark.parametrize("code", sorted(CODES))
def test_explain_every_code(code: str, capsys) -> None:
    assert main(["explain", code]) == 0
    page = capsys.readouterr().out
    assert page.startswith(f"# {code}")


def test_explain_unknown_code_is_usage_error(capsys) -> None:
    assert main(["explain", "MT9999"]) == 2


def test_dump_timeline_and_ast(capsys) -> None:
    assert main(["check", "--dump", "timeline", FLAGSHIP]) == 0
    (timeline,) = json.loads(capsys.readouterr().out)
    assert timeline["task"] == "remove_access_panel"
    assert main(["check", "--dump", "ast", FLAGSHIP]) == 0
    assert json.loads(capsys.readouterr().out)["node"] == "Module"


def test_manikin_override(capsys) -> None:
    assert main(["check", "--dump", "timeline", "--manikin", "gb10000_1988:male:95", FLAGSHIP]) == 0
    (timeline,) = json.loads(capsys.readouterr().out)
    assert timeline["manikin"] == {"population": "gb10000_1988", "sex": "male", "percentile": 95}


def test_compile_writes_and_is_byte_identical(tmp_path: Path) -> None:
    """The command's file is, to the byte, the IR of a compile made in another process or
    earlier in this one (the suite's shared compile of the example, ``example_ir``)."""
    from mtlc.ir.serialize import to_json

    assert main(["compile", FLAGSHIP, "--target", "ir", "-o", str(tmp_path / "a")]) == 0
    (a,) = (tmp_path / "a").iterdir()
    assert a.read_text(encoding="utf-8") == to_json(example_ir(ROOT / FLAGSHIP))
    assert json.loads(a.read_text())["source"]["task"] == "remove_access_panel"


def test_failed_compile_leaves_existing_output_untouched(tmp_path: Path) -> None:
    out = tmp_path / "out"
    src = tmp_path / "job.mtask"
    src.write_text((ROOT / FLAGSHIP).read_text().replace("    walk_to(bench_front)\n", ""))
    assert main(["compile", str(src), "-o", str(out)]) == 0
    (target,) = out.iterdir()
    before = target.read_bytes()
    src.write_text(src.read_text().replace("walk_to(panel_front)", "walk_to(panel_frnt)"))
    assert main(["compile", str(src), "-o", str(out)]) == 1
    assert target.read_bytes() == before
    assert [p.name for p in out.iterdir()] == [target.name]  # no temporary files left behind


def test_include_dir(tmp_path: Path) -> None:
    lib = tmp_path / "lib" / "bay"
    lib.mkdir(parents=True)
    (lib / "scenes.mtask").write_text("scene bay {\n    site a at (0, 100, 40) cm\n}\n")
    main_file = tmp_path / "work" / "main.mtask"
    main_file.parent.mkdir()
    main_file.write_text(
        "use stdlib.actions\nuse bay.scenes\ntask t {\n    scene bay\n    walk_to(a)\n}\n"
    )
    assert main(["check", str(main_file)]) == 1  # not found without -I
    assert main(["check", "-I", str(tmp_path / "lib"), str(main_file)]) == 0


def test_json_with_dump_keeps_stdout_one_document(capsys) -> None:
    assert main(["check", "--format", "json", "--dump", "timeline", FLAGSHIP]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)[0]["task"] == "remove_access_panel"
    assert json.loads(err)["format"] == "mtlc-diagnostics"


def test_compile_refuses_two_tasks_onto_one_file(tmp_path: Path) -> None:
    for d in ("c1", "c2"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "p.mtask").write_text("use stdlib.elements\ntask t {\n    hold(1 s)\n}\n")
    out = tmp_path / "out"
    args = ["compile", "-o", str(out), str(tmp_path / "c1/p.mtask"), str(tmp_path / "c2/p.mtask")]
    assert main(args) == 2
    assert not out.exists()


def test_form_feed_in_a_comment_keeps_the_snippet_on_its_line(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "ff.mtask"
    bad.write_text("# page\f break\ntask t {\n    walk_too()\n}\n")
    assert main(["check", str(bad)]) == 1
    assert "3 |     walk_too()" in capsys.readouterr().err


def test_carets_under_wide_characters(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "cjk.mtask"
    bad.write_text('task t "拆卸面板" {\n    walk_too()\n}\ntask u "拆卸" oops {\n}\n')
    assert main(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    line = next(ln for ln in err.splitlines() if "oops" in ln and "|" in ln)
    caret = err.splitlines()[err.splitlines().index(line) + 1]
    # 拆卸 takes 4 columns: the caret stands under `oops`
    assert caret.index("^") == line.index("oops") + 2


def test_fmt_is_a_command(tmp_path: Path, capsys) -> None:
    messy = tmp_path / "messy.mtask"
    messy.write_text("use   stdlib.actions\ntask t {\n    walk_to( a )\n}\n", encoding="utf-8")
    assert main(["fmt", "--check", str(messy)]) == 1
    assert main(["fmt", str(messy)]) == 0
    assert "use stdlib.actions\n" in messy.read_text(encoding="utf-8")
    assert main(["fmt", "--check", str(messy)]) == 0


def test_preview_is_a_command(tmp_path: Path) -> None:
    page = tmp_path / "motion.html"
    assert main(["preview", "examples/drain_hydraulic_reservoir.mtask", "-o", str(page)]) == 0
    html = page.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") or html.lower().startswith("<!doctype html>")
    assert "mtlcPreview" in html and "drain_reservoir" in html


def test_lint_is_a_command(tmp_path: Path, capsys) -> None:
    src = tmp_path / "job.mtask"
    src.write_text(
        "use stdlib.actions\n\nscene s {\n    site a at (0, 0, 100) cm\n}\n\n"
        "element unused_one() {\n    still over 1 s\n}\n\ntask t {\n    scene s\n    walk_to(a)\n}\n",
        encoding="utf-8",
    )
    assert main(["lint", str(src), "--format", "json"]) == 1
    findings = json.loads(capsys.readouterr().out)["findings"]
    assert [(f["code"], f["span"]["line"]) for f in findings] == [("MT0601", 7)]
    assert main(["lint", str(src), "--exit-zero"]) == 0


def test_report_is_a_command(tmp_path: Path, capsys) -> None:
    csv_path = tmp_path / "report.csv"
    shelf = "tests/report/data/shelf.mtask"
    assert main(["report", shelf, "--manikins", "extremes", "--csv", str(csv_path)]) == 0
    header = csv_path.read_text(encoding="utf-8").splitlines()[0]
    assert header.startswith("task,section,manikin")
    assert "MIL-HDBK-472" in capsys.readouterr().out


# ---------------------------------------------------------------- outputs that cannot be written

TINY = "use stdlib.actions\n\nscene s {\n    site a at (0, 0, 100) cm\n}\n\ntask t {\n    scene s\n    walk_to(a)\n}\n"


def test_compile_with_a_folder_in_the_way_replaces_nothing(tmp_path: Path, capsys) -> None:
    src, out = tmp_path / "job.mtask", tmp_path / "out"
    src.write_text(TINY, encoding="utf-8")
    assert main(["compile", str(src), "--target", "all", "-o", str(out)]) == 0
    script = out / "job.py"
    script.write_text("OLD", encoding="utf-8")
    ir = out / "job.t.ir.json"
    ir.unlink()
    ir.mkdir()
    capsys.readouterr()
    assert main(["compile", str(src), "--target", "all", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"mtlc: cannot write {ir}: it is a folder; nothing was written" in err
    assert "internal error" not in err
    assert script.read_text(encoding="utf-8") == "OLD"


@pytest.mark.parametrize("command", ["lint", "report"])
def test_lint_and_report_output_under_a_file_is_a_usage_error(
    command: str, tmp_path: Path, capsys
) -> None:
    src, blocker = tmp_path / "job.mtask", tmp_path / "file"
    src.write_text(TINY, encoding="utf-8")
    blocker.write_text("", encoding="utf-8")
    args = {"lint": ["--select", "MT0601", "-o"], "report": ["--manikins", "extremes", "--csv"]}
    code = main([command, str(src), *args[command], str(blocker / "x.out")])
    err = capsys.readouterr().err
    assert code == 2
    assert f"mtlc {command}: cannot write {blocker / 'x.out'}: " in err
    assert "internal error" not in err


# ---------------------------------------------------------------- raw CR in a string


def test_a_raw_cr_ends_a_string_like_a_new_line(tmp_path: Path, capsys) -> None:
    """A CR is a line break for positions, so it cannot be inside a string either: otherwise
    every line after it is numbered one too low and suppressions miss their findings."""
    src = tmp_path / "rawcr.mtask"
    text = (
        "use stdlib.actions\n\nscene s {\n    site far at (0, 400, 40) cm normal (0, 0, -1)\n}\n\n"
        'task t "x\ry" {\n    scene s\n    press(right, far) # mtlc: ignore[MT0501]\n}\n'
    )
    src.write_bytes(text.encode("utf-8"))
    assert main(["lint", str(src), "--select", "MT0501,MT0606", "--format", "json"]) == 1
    findings = json.loads(capsys.readouterr().out)["findings"]
    lines = {(f["code"], f["span"]["line"]) for f in findings}
    assert ("MT0103", 7) in lines  # the string ends at the CR: not closed on its line
    assert ("MT0606", 10) in lines and ("MT0501", 9) not in lines  # not shifted a line up


def test_an_unclosed_string_in_a_cr_only_file_is_an_error_on_its_line(
    tmp_path: Path, capsys
) -> None:
    src = tmp_path / "cr.mtask"
    src.write_bytes(b'task t {\r    f("abc\r    g()\r}\r')
    assert main(["check", str(src), "--format", "json"]) == 1
    diagnostics = json.loads(capsys.readouterr().out)["diagnostics"]
    assert ("MT0103", 2) in {(d["code"], d["span"]["line"]) for d in diagnostics}


# ---------------------------------------------------------------- file names that are not UTF-8


def test_a_file_name_that_is_not_utf8_compiles_and_previews(tmp_path: Path) -> None:
    name = os.fsdecode(b"bad\xffname.mtask")
    src = tmp_path / name
    src.write_text(TINY, encoding="utf-8")
    out = tmp_path / "out"
    args = ["compile", str(src), "--target", "all", "--source-map", "-o", str(out)]
    assert main(args) == 0
    assert main(["preview", str(src), "-o", str(out / "p.html")]) == 0
    ir = json.loads((out / os.fsdecode(b"bad\xffname.t.ir.json")).read_bytes().decode("utf-8"))
    assert ir["source"]["file"].endswith(name)  # reads back as the same (undecodable) name
    for path in out.iterdir():
        path.read_bytes().decode("utf-8")  # every output is valid UTF-8


@pytest.mark.parametrize(("command", "module", "inner"), [("lint", "mtlc.lint.command", "_lint"), ("report", "mtlc.report.command", "_report")])  # fmt: skip
def test_a_bug_in_lint_or_report_is_one_line_and_exit_2(
    command: str, module: str, inner: str, monkeypatch, capsys
) -> None:
    import importlib

    def boom(*args: object) -> int:
        raise RuntimeError("boom")

    monkeypatch.setattr(importlib.import_module(module), inner, boom)
    assert main([command, FLAGSHIP]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"mtlc {command}: internal error: RuntimeError: boom (MT0900; "
        "rerun with MTLC_DEBUG=1 for the trace and report it)\n"
    )


@pytest.mark.parametrize(
    ("args", "loaded", "not_loaded"),
    [
        (["--version"], [], ["numpy", "lark", "mtlc.frontend"]),
        (["explain", "MT0201"], [], ["numpy", "lark", "mtlc.frontend"]),
        (["--help"], [], ["numpy", "lark", "mtlc.frontend"]),
        (["check", FLAGSHIP], ["lark", "mtlc.frontend"], ["numpy", "scipy", "mtlc.passes"]),
    ],
)
def test_each_command_imports_only_what_it_uses(
    args: list[str], loaded: list[str], not_loaded: list[str]
) -> None:
    """Issue 21: start-up was 1-2 s of every command, the motion passes and scipy loaded to
    print a version. A fresh interpreter runs the command, then lists what it imported."""
    code = (
        "import sys, contextlib, io\n"
        "from mtlc.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
        "    try:\n"
        f"        main({args!r})\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print(' '.join(sorted(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    modules = set(out.stdout.split())
    assert modules, out.stderr
    assert all(m in modules for m in loaded), [m for m in loaded if m not in modules]
    assert not modules & set(not_loaded), sorted(modules & set(not_loaded))


@pytest.mark.parametrize("columns", ["40", "80", "200"])
def test_the_listing_of_commands_is_the_whole_command_lines_help(
    columns: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`mtlc --help` lists the commands from COMMAND_SUMMARIES without importing them (issue
    21): the same text as the help of the parser that has every command and its options."""
    from mtlc.cli import build_parser, listing_parser

    monkeypatch.setenv("COLUMNS", columns)
    assert listing_parser().format_help() == build_parser().format_help()
