"""Blender imports every example's BVH as we meant it (scripts/check_blender.sh).

In Blender's own coordinates: frame count and rate, feet on the ground, every hand at its goal
site at each TO end and every joint at the first, within 1 mm of the compile's own IR. Runs
where `blender` is on PATH (.ci/run installs it, so CI runs it); elsewhere it skips with one line
saying what to install. One Blender process for the examples, one more for wrong expectations
that must fail. The examples' BVH and IR are written from the compiles the suite's other tests
share (``compiled_example``), so the script checks them without compiling them again
(``--compiled``); `scripts/check_blender.sh` run by hand compiles them itself.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import compiled_example

from mtlc.codegen import GenerateOptions, generate_file

# Local, not from conftest: another conftest module under tests/ can shadow the root one.
ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
HELPER = "scripts/blender_check_bvh.py"
BLENDER_MISSING = "Blender is not installed: apt-get install blender (scripts/check_blender.sh installs it as root)"

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason=BLENDER_MISSING)


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess]:
    out = tmp_path_factory.mktemp("blender")
    for path in EXAMPLES:
        files = generate_file(path.stem, compiled_example(path).motions,
                              GenerateOptions(targets=("bvh", "ir")))  # fmt: skip
        for name, text in files.items():
            (out / name).write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    env = {**os.environ, "PYTHON": sys.executable}
    if "PYTHONPATH" in os.environ or not _importable_from(sys.executable):
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])
    run = subprocess.run(
        ["bash", str(ROOT / "scripts" / "check_blender.sh"), "--compiled", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=900,
    )
    return out, run


def _importable_from(python: str) -> bool:
    run = subprocess.run([python, "-c", "import mtlc"], capture_output=True, timeout=60)
    return run.returncode == 0


def test_blender_shows_every_example_as_the_ir_says(checked) -> None:
    out, run = checked
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"{len(EXAMPLES)} BVH files checked" in run.stdout
    assert run.stdout.count("\nok   ") + run.stdout.startswith("ok   ") == len(EXAMPLES)
    assert len(list(out.glob("*.expected.json"))) == len(EXAMPLES)
    assert len(list(out.glob("*.bvh"))) == len(EXAMPLES)
    summaries = [line for line in run.stdout.splitlines() if " fps; feet: " in line]
    assert len(summaries) == len(EXAMPLES)
    for line in summaries:
        assert "frames at 30.0000 fps" in line
    total_ends = 0
    for expected in out.glob("*.expected.json"):
        doc = json.loads(expected.read_text(encoding="utf-8"))
        assert doc["standing_frames"] and doc["to_ends"]
        total_ends += len(doc["to_ends"])
    assert total_ends >= 20  # every hand's TO end of the four examples, not a sample


def test_blender_check_fails_on_wrong_expectations(checked) -> None:
    """The check is not vacuous: a goal 2 mm off, a floor 2 mm higher or lower and another frame
    rate each make Blender's run fail with the reason."""
    out, _ = checked
    expected = out / "drain_hydraulic_reservoir.drain_reservoir.expected.json"
    bvh = out / "drain_hydraulic_reservoir.drain_reservoir.bvh"
    good = json.loads(expected.read_text(encoding="utf-8"))
    wrongs: dict[str, dict] = {}
    goal = json.loads(json.dumps(good))
    goal["to_ends"][0]["goal"][0] += 0.002
    wrongs["goal"] = goal
    wrongs["high_floor"] = {**good, "ground": good["ground"] + 0.002}
    wrongs["low_floor"] = {**good, "ground": good["ground"] - 0.002}
    wrongs["fps"] = {**good, "fps": 25.0}
    args = []
    for name, doc in wrongs.items():
        path = out / f"wrong_{name}.json"
        path.write_text(json.dumps(doc), encoding="utf-8")
        args += [str(bvh), str(path)]
    blender = ["blender", "--background", "--factory-startup", "--python-exit-code", "1"]
    run = subprocess.run(
        [*blender, "--python", HELPER, "--", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert run.returncode == 1
    fails = {
        name: [ln for ln in run.stderr.splitlines() if f"wrong_{name}.json" in ln]
        for name in wrongs
    }
    assert any("r_hand" in ln and "from drain_valve" in ln for ln in fails["goal"]), run.stderr
    assert any("below the floor" in ln for ln in fails["high_floor"]), run.stderr
    assert any("above the floor" in ln for ln in fails["low_floor"]), run.stderr
    assert any("the IR at 25.0 fps" in ln for ln in fails["fps"]), run.stderr
    assert run.stdout.count("FAIL ") == len(wrongs)
