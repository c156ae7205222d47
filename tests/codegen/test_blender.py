"""Blender imports every example's BVH as we wrote it (scripts/check_blender.sh).

Runs only where `blender` is on PATH (the script installs it with apt-get when run by hand; the
suite never installs anything). About 15 s: four background Blender runs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import EXAMPLES, ROOT

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="blender is not installed")


def test_blender_imports_every_example_within_a_millimetre(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHON": sys.executable}
    run = subprocess.run(
        ["bash", str(ROOT / "scripts" / "check_blender.sh"), str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"{len(EXAMPLES)} BVH files checked" in run.stdout
    assert run.stdout.count("ok   ") == len(EXAMPLES)
    assert len(list(tmp_path.glob("*.expected.json"))) == len(EXAMPLES)


def test_blender_check_fails_on_a_wrong_expectation(tmp_path: Path) -> None:
    """The check is not vacuous: a hand expected 2 mm off makes Blender's run fail."""
    helper = "scripts/blender_check_bvh.py"
    expect = [sys.executable, helper, "expect", str(EXAMPLES[0]), str(tmp_path), "--emit"]
    subprocess.run(expect, check=True, cwd=ROOT)
    (expected,) = tmp_path.glob("*.expected.json")
    bvh = tmp_path / expected.name.replace(".expected.json", ".bvh")
    wrong = json.loads(expected.read_text(encoding="utf-8"))
    wrong["hand"][1] += 0.002
    expected.write_text(json.dumps(wrong), encoding="utf-8")
    blender = ["blender", "--background", "--factory-startup", "--python-exit-code", "1"]
    check = [*blender, "--python", helper, "--", str(bvh), str(expected)]
    run = subprocess.run(check, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 1
    assert "FAIL" in run.stderr and "2.000 mm" in run.stderr
