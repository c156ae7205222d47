"""Golden tests: the AST of every example and stdlib file, the timeline of every example."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import EXAMPLES, ROOT, STDLIB

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.semantics.timeline import PRIMITIVE_KINDS
from mtlc.syntax import parse_module
from mtlc.syntax.dump import dump_module


@pytest.mark.parametrize("path", EXAMPLES + STDLIB, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_ast_golden(path: Path, golden) -> None:
    sink = DiagnosticSink()
    rel = path.relative_to(ROOT).as_posix()
    module = parse_module(path.read_text(encoding="utf-8"), rel, sink)
    assert sink.items == []
    golden.check(f"ast/{path.parent.name}.{path.stem}.json", dump_module(module))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_timeline_golden(path: Path, golden) -> None:
    program = run_frontend([path.relative_to(ROOT)])
    assert program.diagnostics == []
    assert len(program.timelines) == 1
    golden.check(f"timeline/{path.stem}.json", program.timelines[0].to_json())


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_output_is_deterministic(path: Path) -> None:
    first = run_frontend([path.relative_to(ROOT)]).timelines[0].to_json()
    second = run_frontend([path.relative_to(ROOT)]).timelines[0].to_json()
    assert first == second


def test_timeline_is_well_formed() -> None:
    """Invariants every timeline keeps, whatever the goldens say."""
    for path in EXAMPLES:
        doc = json.loads(run_frontend([path.relative_to(ROOT)]).timelines[0].to_json())
        assert doc["format"] == "mtlc-timeline" and doc["version"] == 1
        for prim in doc["primitives"]:
            assert prim["kind"] in PRIMITIVE_KINDS
            assert 0 <= prim["start"] <= prim["end"] <= doc["duration"]
            assert prim["path"].startswith(doc["task"])
            assert prim["origin"]["file"] == path.relative_to(ROOT).as_posix()
            if prim["kind"] == "goal":
                ta, to = prim["params"]["phases"]["TA"], prim["params"]["phases"]["TO"]
                assert ta[0] == prim["start"] and ta[1] == to[0] and to[1] == prim["end"]
