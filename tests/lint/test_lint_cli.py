"""`mtlc lint` as a command: exit codes, --exit-zero, --fail-on, configuration, -o, -m."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mtlc.lint.command import main

BAY = "tests/lint/data/bay.mtask"


@pytest.fixture
def program_only(tmp_path: Path) -> Path:
    """A configuration with the rules that need no motion (keeps these tests fast): the
    program's rules (unused definitions and parameters, unused suppressions), the budgets and
    the front end's codes. ``MT06`` as a whole would take the motion rules and so compile the
    motion for both manikins."""
    cfg = tmp_path / "mtlc.toml"
    select = '["MT0601", "MT0602", "MT0606", "MT04", "MT02", "MT03"]'
    cfg.write_text(f"[lint]\nselect = {select}\n", encoding="utf-8")
    return cfg


def test_findings_exit_1_and_exit_zero_exits_0(program_only: Path, capsys) -> None:
    assert main([BAY, "--config", str(program_only)]) == 1
    assert "warning[MT0601]" in capsys.readouterr().out
    assert main([BAY, "--config", str(program_only), "--exit-zero"]) == 0
    assert main([BAY, "--config", str(program_only), "--fail-on", "error"]) == 0


def test_clean_file_exits_0(program_only: Path, tmp_path: Path, capsys) -> None:
    clean = tmp_path / "clean.mtask"
    clean.write_text("use stdlib.actions\nscene s {\n    site a at (0, 100, 50) cm\n}\n"
                     "task t {\n    scene s\n    inspect(a)\n}\n", encoding="utf-8")  # fmt: skip
    assert main([str(clean), "--config", str(program_only)]) == 0
    assert "no findings" in capsys.readouterr().out


def test_syntax_errors_are_findings_not_tracebacks(
    program_only: Path, tmp_path: Path, capsys
) -> None:
    bad = tmp_path / "bad.mtask"
    bad.write_text("task t {\n    @@\n}\n", encoding="utf-8")
    assert main([str(bad), "--config", str(program_only), "--format", "json"]) == 1
    assert '"code": "MT0102"' in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [["--manikins", "gb10000_1988:male:3"], ["--manikins", "everyone"]],
)
def test_usage_errors_exit_2(argv: list[str], capsys) -> None:
    assert main([BAY, *argv]) == 2
    assert "mtlc lint:" in capsys.readouterr().err


def test_missing_path_and_bad_config_exit_2(tmp_path: Path, capsys) -> None:
    assert main([str(tmp_path / "nope.mtask")]) == 2
    cfg = tmp_path / "mtlc.toml"
    cfg.write_text("[lint]\nrula_threshold = 4\n", encoding="utf-8")
    assert main([BAY, "--config", str(cfg)]) == 2
    assert "unknown key" in capsys.readouterr().err


def test_folders_are_walked_and_output_goes_to_a_file(program_only: Path, tmp_path: Path) -> None:
    out = tmp_path / "lint.sarif"
    code = main(
        ["tests/lint/data", "--config", str(program_only), "--format", "sarif", "-o", str(out)]
    )
    assert code == 1
    assert '"uri": "tests/lint/data/bay.mtask"' in out.read_text(encoding="utf-8")


def test_the_program_only_configuration_compiles_no_motion(program_only: Path) -> None:
    """What keeps the tests above fast: none of its codes is one that only the motion finds."""
    from mtlc.lint.config import load_config
    from mtlc.lint.engine import MOTION_CODES

    config = load_config(program_only.parent, program_only)
    assert config.enabled("MT0601") and config.enabled("MT0404")
    assert not any(config.enabled(code) for code in MOTION_CODES)


def test_python_dash_m_runs_the_command() -> None:
    done = subprocess.run([sys.executable, "-m", "mtlc.lint", "--help"], capture_output=True,
                          text=True, check=False)  # fmt: skip
    assert done.returncode == 0 and "--manikins" in done.stdout


def test_select_and_ignore_on_the_command_line(capsys) -> None:
    assert main([BAY, "--select", "MT0601,unused-parameter", "--format", "json"]) == 1
    out = capsys.readouterr().out
    assert '"MT0601"' in out and '"MT0602"' in out and '"MT0404"' not in out
    assert main([BAY, "--select", "MT06", "--ignore", "MT0601,MT0602,MT0606,MT0607"]) == 0
    assert main([BAY, "--select", "MT0999"]) == 2


def test_ci_workflow_and_hooks_run_real_options() -> None:
    """The workflow in docs/ci.md and the pre-commit hooks use options the command has."""
    import argparse
    import re
    import shlex

    import yaml

    from mtlc.lint.command import configure_parser

    parser = argparse.ArgumentParser(exit_on_error=False)
    configure_parser(parser)
    text = Path("docs/ci.md").read_text(encoding="utf-8")
    workflow = yaml.safe_load(re.findall(r"```yaml\n(.*?)```", text, re.S)[0])
    runs = [s["run"] for s in workflow["jobs"]["lint"]["steps"] if "mtlc.lint" in s.get("run", "")]
    hooks = yaml.safe_load(Path(".pre-commit-hooks.yaml").read_text(encoding="utf-8"))
    runs += [h["entry"] + " x.mtask" for h in hooks]
    assert len(runs) == 4
    for run in runs:
        argv = shlex.split(run)
        assert argv[:3] == ["python", "-m", "mtlc.lint"]
        parser.parse_args(argv[3:])  # raises on an unknown option


def test_a_suppression_of_an_unchecked_code_is_not_unused(capsys) -> None:
    assert (
        main([BAY, "--select", "MT06", "--ignore", "MT0603,MT0604,MT0605", "--format", "json"]) == 1
    )
    out = capsys.readouterr().out
    assert "MT0502; the suppression" not in out  # balance was not checked
    assert '"line": 11' in out and '"line": 15' in out


def test_an_ignore_comment_of_a_retired_code_is_not_unused(tmp_path: Path, capsys) -> None:
    """MT0520 and MT0525 are retired (verify reports their faults as MT0511 and MT0512): their
    codes stay in the table, and an old ignore comment naming them is neither unknown nor
    unused, so a CI lint that passed does not start failing on it."""
    path = tmp_path / "old.mtask"
    path.write_text("use stdlib.actions\nscene s {\n    site a at (0, 100, 50) cm\n}\n"
                    "task t {  # mtlc: ignore[MT0520, fingertips-under-floor, MT0599]\n"
                    "    scene s\n    inspect(a)\n}\n", encoding="utf-8")  # fmt: skip
    # MT0606 and the retired codes only: no motion is compiled (fast)
    main([str(path), "--select", "MT0606,MT0520,MT0525", "--format", "json"])
    out = capsys.readouterr().out
    assert "MT0520" not in out and "fingertips-under-floor" not in out, out
    assert "`MT0599` is not a diagnostic code" in out  # an unknown one still is


def test_explain_a_retired_code_names_the_code_that_replaced_it(capsys) -> None:
    from mtlc.cli import main as mtlc_main
    from mtlc.diagnostics import CODES, RETIRED

    assert set(RETIRED) == {"MT0520", "MT0525"}
    for code, now in (("MT0520", "MT0511"), ("MT0525", "MT0512")):
        assert CODES[code].retired_for == now
        assert mtlc_main(["explain", code]) == 0
        assert f"Retired: see [{now}]" in capsys.readouterr().out
