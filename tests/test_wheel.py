"""The built wheel carries the grammar, the stdlib and the diagnostic pages, and works alone."""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest
from conftest import ROOT


@pytest.mark.slow
def test_wheel_installs_and_checks_an_example_outside_the_checkout(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "build",
            "--wheel",
            "--no-isolation",
            "--outdir",
            str(dist),
            str(ROOT),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = dist.glob("mtlc-*.whl")

    import zipfile

    names = set(zipfile.ZipFile(wheel).namelist())
    assert "mtlc/_resources/grammar/mtask.lark" in names
    assert "mtlc/_resources/stdlib/actions.mtask" in names
    assert "mtlc/_resources/diagnostics/MT0201.md" in names
    assert "mtlc/data/time_standards/mtm1_reach_move.csv" in names
    assert "mtlc/body/data/gb10000_1988.csv" in names

    # the dependencies come from this interpreter's site-packages; mtlc itself from the wheel only
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True, system_site_packages=True).create(env_dir)
    py = env_dir / "bin" / "python"
    install = subprocess.run(
        [str(py), "-m", "pip", "install", "--no-deps", "--no-index", "--quiet", str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert install.returncode == 0, install.stderr

    work = tmp_path / "elsewhere"
    work.mkdir()
    example = work / "panel.mtask"
    example.write_text((ROOT / "examples" / "remove_access_panel.mtask").read_text())
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    where = subprocess.run(
        [str(py), "-c", "import mtlc, mtlc.resources as r; print(mtlc.__file__); print(r.stdlib_dir())"],
        capture_output=True, text=True, cwd=work, env=env, timeout=60,
    )  # fmt: skip
    mtlc_file, stdlib = where.stdout.split()
    assert Path(mtlc_file).is_relative_to(env_dir), where.stdout
    assert Path(stdlib).is_relative_to(env_dir)

    check = subprocess.run(
        [str(env_dir / "bin" / "mtlc"), "check", "panel.mtask"],
        capture_output=True, text=True, cwd=work, env=env, timeout=120,
    )  # fmt: skip
    assert check.returncode == 0, check.stderr
    assert "ok: 1 file, 1 task" in check.stderr
    explain = subprocess.run(
        [str(env_dir / "bin" / "mtlc"), "explain", "MT0201"],
        capture_output=True, text=True, cwd=work, env=env, timeout=60,
    )  # fmt: skip
    assert explain.returncode == 0 and explain.stdout.startswith("# MT0201")
