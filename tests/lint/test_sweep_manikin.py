"""Lint and report judge each manikin on the motion `mtlc compile --manikin` gives it.

A walk's steps take the time of the body's gait (stature and sex, ``semantics.gait``), so a
task's timeline depends on the manikin. Lint and report sweep manikins other than the task's
own: each must get the timeline compile gives that manikin (``frontend.time_task``), not the
task's own manikin's timing with another skeleton (lint's female P1 once walked the first walk
of remove_access_panel in 1.29 s, compile --manikin gave her 1.93 s).

The seam: the timeline lint and report hand to the motion passes (``run_motion``, recorded
here), against the one compile hands them (``cli.cmd_compile``: the front end with
``--manikin``). The motion passes are a function of the timeline; one test also runs them and
compares the IR, and the diagnostics lint and compile report for each manikin.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mtlc.lint.engine
import mtlc.report.analysis
from mtlc.diagnostics import CODES, DiagnosticSink
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.manikins import label, parse_selection
from mtlc.passes import run_motion
from mtlc.report import analyse_task
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec, Timeline

ROUNDS = Path("tests/lint/data/rounds.mtask")  # walks and turns of many lengths
FILES = [*sorted(Path("examples").glob("*.mtask")), ROUNDS]
# the extremes of the table and one between, none of them every file's own manikin
SWEPT = parse_selection("gb10000_1988:female:1,gb10000_1988:female:50,gb10000_1988:male:99")
NO_RULES = LintConfig(select=frozenset(c for c in CODES if not c.startswith("MT06")))


class Recorded(Exception):
    """Raised in place of the motion passes once their input is recorded."""


def compile_timelines(path: Path, spec: ManikinSpec) -> list[Timeline]:
    """What `mtlc compile FILE --manikin SPEC` hands the motion passes (cli.cmd_compile)."""
    program = run_frontend([path], FrontendOptions(manikin=spec))
    assert not program.sink.has_errors
    return program.timelines


def recorder(seen: list[Timeline], run: bool) -> Any:
    def record(timeline: Timeline, sink: DiagnosticSink, options: Any = None, **kw: Any) -> Any:
        seen.append(timeline)
        if not run:
            raise Recorded  # lint: MT0900 for this task and manikin; report: a failed row
        return run_motion(timeline, sink, options, **kw)

    return record


def patch_motion(monkeypatch: pytest.MonkeyPatch, seen: list[Timeline], run: bool) -> None:
    # lint's and report's name for the motion passes
    monkeypatch.setattr(mtlc.lint.engine, "run_motion", recorder(seen, run))
    monkeypatch.setattr(mtlc.report.analysis, "run_motion", recorder(seen, run))


def primitives_of(timeline: Timeline) -> list[tuple[Any, ...]]:
    """Every primitive's kind, times (exact), parameters and source line."""
    return [
        (p.kind, p.effector, p.start, p.end, p.params, p.path, p.origin)
        for p in timeline.primitives
    ]


def same_timeline(got: Timeline, want: Timeline) -> None:
    assert got.manikin == want.manikin
    assert got.task == want.task
    assert primitives_of(got) == primitives_of(want)
    assert got.as_dict() == want.as_dict()


def walks(timeline: Timeline) -> list[tuple[float, float]]:
    return [(p.start, p.end) for p in timeline.primitives if p.kind == "locomotion"]


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_lint_compiles_each_manikin_on_compiles_timeline(
    path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: list[Timeline] = []
    patch_motion(monkeypatch, seen, run=False)
    lint_paths([path], NO_RULES, manikins=SWEPT, jobs=1)
    want = [t for spec in SWEPT for t in compile_timelines(path, spec)]
    assert len(seen) == len(want)  # one task a file: in selection order
    for got, expected in zip(seen, want, strict=True):
        same_timeline(got, expected)


@pytest.mark.parametrize("path", [Path("examples/remove_access_panel.mtask"), ROUNDS])
def test_report_measures_each_manikin_on_compiles_timeline(
    path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (timeline,) = run_frontend([path]).timelines  # timed for the task's own manikin
    seen: list[Timeline] = []
    patch_motion(monkeypatch, seen, run=False)
    task = analyse_task(timeline, SWEPT, jobs=1)
    assert [m.method for m in task.manikins] == ["failed"] * len(SWEPT)
    for got, spec, row in zip(seen, SWEPT, task.manikins, strict=True):
        (expected,) = compile_timelines(path, spec)
        same_timeline(got, expected)
        assert row.time == expected.duration  # the row's predicted time is this manikin's


def test_the_sweep_times_walks_for_each_body() -> None:
    """The premise: the swept manikins' walks do not all take the same time (else the tests
    above could not fail), and the task's own manikin gets the time it always had."""
    for path in (Path("examples/remove_access_panel.mtask"), ROUNDS):
        timed = {spec: compile_timelines(path, spec)[0] for spec in SWEPT}
        assert len({tuple(walks(t)) for t in timed.values()}) == len(SWEPT)
        (own,) = run_frontend([path]).timelines
        (again,) = compile_timelines(path, own.manikin)
        same_timeline(own, again)


def test_the_motion_passes_refuse_a_manikin_the_walks_are_not_timed_for() -> None:
    """Replacing the manikin of a timed timeline (what the sweeps did) keeps the other body's
    walk times: run_motion refuses it, and the same timeline timed again runs."""
    (own,) = run_frontend([ROUNDS]).timelines
    other = SWEPT[0]
    with pytest.raises(ValueError, match="not timed for gb10000_1988:female:1"):
        run_motion(dataclasses.replace(own, manikin=other), DiagnosticSink(), until="manikin")
    timed = schedule.for_manikin(own, other)
    (expected,) = compile_timelines(ROUNDS, other)
    same_timeline(timed, expected)
    assert run_motion(timed, DiagnosticSink(), until="manikin").manikin["sex"] == "female"


def ir_key(ir: MotionIR) -> list[tuple[Any, ...]]:
    return [(s.track, s.kind, s.start, s.end) for s in ir.segments]


def same_motion(got: MotionIR, want: MotionIR) -> None:
    assert got.manikin == want.manikin
    assert ir_key(got) == ir_key(want)
    assert got.frames is not None and want.frames is not None
    for name in ("time", "root_position", "root_rotation", "q"):
        a, b = getattr(got.frames, name), getattr(want.frames, name)
        assert a.shape == b.shape, name
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, err_msg=name)


def test_lint_motion_and_diagnostics_are_compiles(monkeypatch: pytest.MonkeyPatch) -> None:
    """The walks and turns procedure through the motion passes for three manikins: lint's IR
    is compile's (every segment's times, frames within 1e-9), and the MT codes lint reports
    for a manikin are those compile reports for it, at the same lines."""
    irs: list[MotionIR] = []
    seen: list[Timeline] = []
    record = recorder(seen, run=True)

    def keep(timeline: Timeline, sink: DiagnosticSink, options: Any = None, **kw: Any) -> Any:
        irs.append(record(timeline, sink, options, **kw))
        return irs[-1]

    monkeypatch.setattr(mtlc.lint.engine, "run_motion", keep)
    findings = lint_paths([ROUNDS], NO_RULES, manikins=SWEPT, jobs=1).findings
    assert len(irs) == len(SWEPT)
    # its budget (36.2 s) is over for some bodies' walking and not others: MT0404 is a verdict
    # per manikin, as compile gives it
    (over,) = [f for f in findings if f.code == "MT0404"]
    assert 0 < len(over.manikins) < len(SWEPT)
    for ir, spec in zip(irs, SWEPT, strict=True):
        program = run_frontend([ROUNDS], FrontendOptions(manikin=spec))
        (timeline,) = program.timelines
        same_motion(ir, run_motion(timeline, program.sink))
        compiled = sorted({(d.code, d.span.line, d.span.column) for d in program.diagnostics})
        linted = sorted(
            {
                (f.code, f.span.line, f.span.column)
                for f in findings
                if not f.manikins or label(spec) in f.manikins
            }
        )
        assert linted == compiled, label(spec)
