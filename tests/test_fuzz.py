"""bench/fuzz.py's cases, in process: no traceback, no internal error, fmt idempotent.

1,000 cases (generated from the grammar and the stdlib, and mutations of the examples) through
`check` and `fmt`; a few clean ones through the motion passes and every generator. The full
run, with lint, the serve endpoints, time limits and memory, is `python bench/fuzz.py`.
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
from pathlib import Path

import pytest
from conftest import ROOT

_spec = importlib.util.spec_from_file_location("mtlc_bench_fuzz", ROOT / "bench" / "fuzz.py")
assert _spec is not None and _spec.loader is not None
fuzz = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = fuzz
_spec.loader.exec_module(fuzz)

SEED = 17
CASES = 1000
BAD = ("traceback", "internal", "nonidempotent", "memory")


def test_cases_are_deterministic_and_varied() -> None:
    sources = fuzz.example_sources()
    first = [fuzz.make_case(SEED, i, sources) for i in range(8)]
    assert first == [fuzz.make_case(SEED, i, sources) for i in range(8)]
    assert {origin for origin, _ in first} == {"generated", "mutated"}
    assert len({data for _, data in first}) == 8


@pytest.fixture(scope="module")
def outcomes() -> list[tuple[int, str, str, object]]:
    sources = fuzz.example_sources()
    found = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "case.mtask"
        for index in range(CASES):
            origin, data = fuzz.make_case(SEED, index, sources)
            path.write_bytes(data)
            for stage in ("check", "fmt"):
                found.append((index, origin, stage, fuzz.run_stage(stage, path, SEED, index)))
    return found


def test_a_thousand_cases_check_and_format_without_a_crash(outcomes: list) -> None:  # type: ignore[type-arg]
    bad = [
        f"{stage} case {index} ({origin}): {out.status}: {out.detail}"
        for index, origin, stage, out in outcomes
        if out.status in BAD
    ]
    assert bad == []


def test_the_cases_reach_every_stage(outcomes: list) -> None:  # type: ignore[type-arg]
    """Enough cases check clean (for compile) and format (for idempotence) to mean something."""
    clean = sum(out.clean for _, _, stage, out in outcomes if stage == "check")
    formatted = sum(out.status == "ok" for _, _, stage, out in outcomes if stage == "fmt")
    assert clean >= CASES // 20
    assert formatted >= CASES // 4


def test_clean_cases_compile_to_every_target(outcomes: list) -> None:  # type: ignore[type-arg]
    sources = fuzz.example_sources()
    clean = [i for i, _, stage, out in outcomes if stage == "check" and out.clean][:3]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "case.mtask"
        for index in clean:
            path.write_bytes(fuzz.make_case(SEED, index, sources)[1])
            out = fuzz.run_stage("compile", path, SEED, index)
            assert out.status == "ok", (index, out.detail)
