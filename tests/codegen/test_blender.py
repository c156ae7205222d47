"""Blender imports every example's BVH as we wrote it (scripts/check_blender.sh).

Runs only where `blender` is on PATH (the script installs it with apt-get when run by hand; the
suite never installs anything). Four background Blender imports, then one more that must fail.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

# Local, not from conftest: another conftest module under tests/ can shadow the root one.
ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
HELPER = "scripts/blender_check_bvh.py"

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="blender is not installed")


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess]:
    out = tmp_path_factory.mktemp("blender")
    run = subprocess.run(
        ["bash", str(ROOT / "scripts" / "check_blender.sh"), str(out)],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHON": sys.executable},
        cwd=ROOT,
        timeout=900,
    )
    return out, run


def test_blender_imports_every_example_within_a_millimetre(checked) -> None:
    out, run = checked
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"{len(EXAMPLES)} BVH files checked" in run.stdout
    assert run.stdout.count("ok   ") == len(EXAMPLES)
    assert len(list(out.glob("*.expected.json"))) == len(EXAMPLES)
    assert len(list(out.glob("*.bvh"))) == len(EXAMPLES)


def test_blender_check_fails_on_a_wrong_expectation(checked) -> None:
    """The check is not vacuous: a hand expected 2 mm off makes Blender's run fail."""
    out, _ = checked
    expected = sorted(out.glob("*.expected.json"))[0]
    bvh = out / expected.name.replace(".expected.json", ".bvh")
    wrong = json.loads(expected.read_text(encoding="utf-8"))
    wrong["hand"][1] += 0.002
    wrong_path = out / "wrong.json"
    wrong_path.write_text(json.dumps(wrong), encoding="utf-8")
    blender = ["blender", "--background", "--factory-startup", "--python-exit-code", "1"]
    check = [*blender, "--python", HELPER, "--", str(bvh), str(wrong_path)]
    run = subprocess.run(check, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 1
    assert "FAIL" in run.stderr and "2.000 mm" in run.stderr
