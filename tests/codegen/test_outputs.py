"""Every target of every example, through the command line, against its golden file.

The goldens are made at 10 frames per second to keep them small; the sampling rate changes how
many frames there are, not how they are computed. They are compared to a tolerance of two units
of the last printed digit (tests/conftest.py); byte identity is checked between two compiles on
this machine. Refresh with `pytest --update-goldens`.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest
from conftest import EXAMPLES, ROOT

from mtlc.cli import main
from mtlc.codegen import python_module_name

GOLDEN_FPS = "10"


def _compile(path: Path, out: Path, *extra: str) -> dict[str, bytes]:
    rel = path.relative_to(ROOT).as_posix()
    argv = ["compile", rel, "-o", str(out), "--target", "all", "--fps", GOLDEN_FPS, *extra]
    assert main(argv) == 0
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> dict[Path, dict[str, bytes]]:
    base = tmp_path_factory.mktemp("outputs")
    return {p: _compile(p, base / p.stem, "--source-map") for p in EXAMPLES}


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_every_target_matches_its_golden(path: Path, outputs, golden) -> None:
    files = outputs[path]
    module = python_module_name(path.stem)
    task_files = [n for n in files if n.endswith((".bvh", ".ir.json"))]
    assert {f"{module}.py", f"{module}.py.map.json"} <= set(files)
    assert any(n.endswith(".bvh") for n in task_files) and any(
        n.endswith(".ir.json") for n in task_files
    )
    for name, data in files.items():
        kind = "jackscript" if name.startswith(f"{module}.py") else name.rsplit(".", 2)[-1]
        kind = "ir" if name.endswith(".ir.json") else kind
        golden.check(f"{kind}/{name}", data.decode("utf-8"))


def test_default_target_is_one_jackscript_module_per_file(tmp_path: Path) -> None:
    path = EXAMPLES[0]
    assert main(["compile", path.relative_to(ROOT).as_posix(), "-o", str(tmp_path)]) == 0
    (script,) = tmp_path.iterdir()
    assert script.name == f"{python_module_name(path.stem)}.py"
    ast.parse(script.read_text(encoding="utf-8"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_every_target_is_byte_identical_on_one_machine(path: Path, tmp_path: Path, outputs) -> None:
    """The goldens allow the last printed digit to differ across BLAS builds (tests/conftest.py);
    on one machine a second compile must give exactly the same bytes, every target, every file."""
    again = _compile(path, tmp_path / "again", "--source-map")
    assert sorted(again) == sorted(outputs[path])
    for name, data in again.items():
        assert data == outputs[path][name], f"{name} differs between two compiles"


def test_source_map_points_into_the_task_file(outputs) -> None:
    for path, files in outputs.items():
        (map_name,) = [n for n in files if n.endswith(".map.json")]
        doc = json.loads(files[map_name])
        lines = path.read_text(encoding="utf-8").splitlines()
        assert doc["script"] == map_name.removesuffix(".map.json")
        text = json.dumps(doc)
        assert path.name in text
        for entry in _spans(doc):
            assert 1 <= entry["line"] <= len(lines), entry


def _spans(doc: object) -> list[dict]:
    """Every object in the map that names a source line."""
    found: list[dict] = []
    if isinstance(doc, dict):
        if "line" in doc and "file" in doc:
            found.append(doc)
        for v in doc.values():
            found.extend(_spans(v))
    elif isinstance(doc, list):
        for v in doc:
            found.extend(_spans(v))
    return found


@pytest.mark.parametrize(
    ("stem", "module"),
    [
        ("remove_access_panel", "remove_access_panel"),
        ("remove-panel v2", "remove_u002dpanel_u0020v2"),
        ("2nd_task", "task_2nd_task"),
        ("class", "class_"),
        ("js", "js_"),
        ("os", "os_"),
        ("string", "string_"),
        ("拆卸", "_u62c6_u5378"),
    ],
)
def test_script_module_names_are_importable(stem: str, module: str) -> None:
    assert python_module_name(stem) == module
    assert module.isidentifier() and module.isascii()


def test_two_files_with_one_stem_are_refused(tmp_path: Path, capsys) -> None:
    src = (ROOT / "examples" / "remove_access_panel.mtask").read_text(encoding="utf-8")
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "job.mtask").write_text(src, encoding="utf-8")
    out = tmp_path / "out"
    argv = ["compile", str(tmp_path / "a/job.mtask"), str(tmp_path / "b/job.mtask"), "-o", str(out)]
    assert main([*argv, "--target", "ir"]) == 2
    assert "would both be written" in capsys.readouterr().err
    assert not out.exists()
