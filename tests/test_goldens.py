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


# -- the tolerant comparison itself ---------------------------------------------------------
BVH_GOLDEN = "MOTION\nFrames: 2\nFrame Time: 0.10000000\n1.000 92.500 -3.141\n0.000 92.512 -3.142\n"


def _golden_dir(tmp_path: Path, relpath: str, text: str):  # type: ignore[no-untyped-def]
    from conftest import Golden

    (tmp_path / relpath).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / relpath).write_text(text, encoding="utf-8")
    return Golden(update=False, root=tmp_path)


def test_tolerant_golden_passes_a_last_digit_that_rounds_the_other_way(tmp_path: Path) -> None:
    golden = _golden_dir(tmp_path, "bvh/x.bvh", BVH_GOLDEN)
    golden.check("bvh/x.bvh", BVH_GOLDEN.replace("92.512", "92.513").replace("-3.141", "-3.140"))


@pytest.mark.parametrize(
    ("old", "new", "why"),
    [
        ("92.512", "92.515", "differs from the golden"),  # a real change: 0.03 mm
        ("-3.142", "-3.152", "differs from the golden"),  # 0.01 degree
        ("Frames: 2", "Frames: 3", "text differs"),  # an integer is structure
        ("0.000 92.512", "0.000  92.512", "text differs"),  # spacing
        ("-3.142\n", "-3.142 0.000\n", "text differs"),  # one value more
        ("MOTION", "M0TION", "text differs"),
        ("-3.142\n", "-3.142\n0.000 0.000 0.000\n", "lines"),  # one line more
    ],
)
def test_tolerant_golden_fails_on_a_real_change(
    tmp_path: Path, old: str, new: str, why: str
) -> None:
    golden = _golden_dir(tmp_path, "bvh/x.bvh", BVH_GOLDEN)
    assert old in BVH_GOLDEN
    with pytest.raises(pytest.fail.Exception, match=why):
        golden.check("bvh/x.bvh", BVH_GOLDEN.replace(old, new, 1))


def test_text_goldens_stay_byte_for_byte(tmp_path: Path) -> None:
    """A timeline (no linear algebra) must not absorb a last-digit change."""
    text = '{"duration":1.5,"start":0.25}\n'
    golden = _golden_dir(tmp_path, "timeline/x.json", text)
    golden.check("timeline/x.json", text)
    with pytest.raises(pytest.fail.Exception, match="text differs"):
        golden.check("timeline/x.json", text.replace("0.25", "0.2500001"))


def test_float_pattern_leaves_names_and_integers_alone() -> None:
    from conftest import FLOAT

    line = "human.KeyJoints(2.8, {'neck': (-57.3291, 1e-05, 0.0)}) # MT0201 bolt_1 v2.3 frame 12"
    assert FLOAT.findall(line) == ["2.8", "-57.3291", "1e-05", "0.0"]
