"""The built wheel carries the grammar, the stdlib and the diagnostic pages, and works alone.

It is installed with its dependencies (from the package index, as a user would) into a venv of
its own without system site packages, then its `mtlc` checks, explains and compiles an example
outside the checkout.
"""

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

    # A clean venv (no system site packages): the wheel brings its dependencies from the index,
    # as for a user; pip's cache keeps a second run quick. The venv gets no pip of its own (this
    # pip installs into it, ``--python``: ensurepip took 8 of the test's 40 s), and pip compiles
    # no bytecode (``--no-compile``: every module of numpy and scipy, 17 s); Python compiles the
    # few modules the commands below import when they import them.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False, system_site_packages=False).create(env_dir)
    py = env_dir / "bin" / "python"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(py), "install", "--quiet",
         "--disable-pip-version-check", "--no-compile", str(wheel)],
        capture_output=True, text=True, env=env, timeout=600,
    )  # fmt: skip
    assert install.returncode == 0, install.stdout + install.stderr
    deps = subprocess.run(
        [str(py), "-c", "import lark, numpy, rich, scipy; print(lark.__file__, numpy.__file__, rich.__file__, scipy.__file__)"],
        capture_output=True, text=True, env=env, timeout=60,
    )  # fmt: skip
    assert deps.returncode == 0, deps.stderr
    assert all(Path(f).is_relative_to(env_dir) for f in deps.stdout.split()), deps.stdout

    work = tmp_path / "elsewhere"
    work.mkdir()
    example = work / "panel.mtask"
    example.write_text((ROOT / "examples" / "remove_access_panel.mtask").read_text())
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
    compiled = subprocess.run(
        [str(env_dir / "bin" / "mtlc"), "compile", "panel.mtask", "-o", "out", "--target", "all"],
        capture_output=True, text=True, cwd=work, env=env, timeout=300,
    )  # fmt: skip
    assert compiled.returncode == 0, compiled.stderr
    written = sorted(p.name for p in (work / "out").iterdir())
    assert written == [
        "panel.py",
        "panel.remove_access_panel.bvh",
        "panel.remove_access_panel.ir.json",
    ], written
    assert (work / "out" / "panel.remove_access_panel.bvh").read_text().startswith("HIERARCHY")
