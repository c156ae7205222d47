"""CI's own script (.ci/run) and the tool installer it relies on (scripts/install_chromium.sh)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

from conftest import ROOT

RUN = ROOT / ".ci" / "run"
INSTALL_CHROMIUM = ROOT / "scripts" / "install_chromium.sh"


def readme_commands() -> list[str]:
    """The shell commands of the README's quick start, in order."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return [c.strip() for c in re.findall(r"```sh\n(.*?)```", text, re.S)]


def test_ci_runs_the_readmes_test_command_verbatim_after_installing_the_tools() -> None:
    run = RUN.read_text(encoding="utf-8")
    test_command = readme_commands()[1]
    assert test_command == "pip install -e '.[test]' && python -m pytest -q"
    assert run.count(test_command) == 1
    at = run.index(test_command)
    assert run.index("sh scripts/install_chromium.sh") < at
    assert run.index("install -y -qq blender") < at
    assert '"$status" -eq 5' in run[at:]  # pytest's "no tests collected" fails CI
    assert os.access(RUN, os.X_OK)


def _installer(tmp_path: Path, chromium: bool, driver: bool) -> subprocess.CompletedProcess:
    """install_chromium.sh with fake binaries and a PATH holding only `id` (no apt-get)."""
    fake = tmp_path / "fake"
    fake.mkdir()
    paths = {}
    for name, present in (("chromium", chromium), ("chromedriver", driver)):
        paths[name] = fake / name
        if present:
            paths[name].write_text("#!/bin/sh\n")
            paths[name].chmod(0o755)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "id").symlink_to(shutil.which("id") or "/usr/bin/id")
    env = {"PATH": str(bin_dir), "CHROMIUM_BIN": str(paths["chromium"])}
    env["CHROMEDRIVER_BIN"] = str(paths["chromedriver"])
    return subprocess.run(
        ["/bin/sh", str(INSTALL_CHROMIUM)], capture_output=True, text=True, env=env, timeout=60
    )


def test_install_chromium_is_a_no_op_when_both_are_there(tmp_path: Path) -> None:
    run = _installer(tmp_path, chromium=True, driver=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout == run.stderr == ""


def test_install_chromium_does_not_stop_at_chromium_without_its_driver(tmp_path: Path) -> None:
    """The bug of issue 17: /usr/bin/chromium alone made the script exit 0, so every browser
    test skipped. Here it goes on to install, and (no apt-get on this PATH) says why it cannot."""
    run = _installer(tmp_path, chromium=True, driver=False)
    assert run.returncode in (3, 4), run.stderr  # 3: not root, 4: no apt-get
    assert "chromium" in run.stderr
