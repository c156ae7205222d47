"""mtlc.executor: the same outcomes in the same order whatever the number of jobs; a worker that
dies fails its one item and the sweep goes on; Ctrl-C stops the workers. And the sweeps that
use it (lint, report) give identical results with 1 and 2 jobs."""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc import executor
from mtlc.executor import Done, Failed
from mtlc.frontend import run_frontend
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.manikins import parse_selection
from mtlc.lint.output import RENDERERS
from mtlc.report import analyse_task

BAY = Path("tests/lint/data/bay.mtask")
SHELF = Path("tests/report/data/shelf.mtask")
TWO = "gb10000_1988:female:5,gb10000_1988:male:95"


def scaled(shared: int, item: int) -> int:
    return shared * item


def misbehaving(shared: int, item: int) -> int:
    """Dies, is killed or raises on some items (module level: workers unpickle it)."""
    if item == 3:
        os._exit(7)
    if item == 5:
        os.kill(os.getpid(), signal.SIGKILL)
    if item == 6:
        raise ValueError("six")
    if item == 8:
        return lambda: None  # type: ignore[return-value]  # cannot be pickled back
    return shared * item


def nested(shared: int, item: int) -> list[int]:
    """A sweep inside a worker runs in that worker (daemons cannot start processes)."""
    return [o.value for o in executor.run(scaled, shared, [item, item + 1], jobs=2)]  # type: ignore[union-attr]


def sleepy(shared: float, item: int) -> int:
    time.sleep(shared)
    return item


@settings(max_examples=10, deadline=None)
@given(st.lists(st.integers(-1000, 1000), max_size=12), st.integers(1, 3))
def test_outcomes_are_in_item_order_whatever_the_jobs(items: list[int], jobs: int) -> None:
    out = executor.run(scaled, 3, items, jobs)
    assert out == [Done(3 * i) for i in items]


def test_a_dead_worker_fails_its_item_only() -> None:
    out = executor.run(misbehaving, 10, list(range(10)), jobs=2)
    assert [type(o) for o in out] == [Done] * 3 + [Failed, Done, Failed, Failed, Done, Failed, Done]
    assert out[3] == Failed("worker process exited with code 7", crashed=True)
    assert out[5] == Failed("worker process killed by signal SIGKILL", crashed=True)
    assert out[6] == Failed("ValueError: six")
    assert isinstance(out[8], Failed) and out[8].message.startswith("result not transferable")
    assert out[9] == Done(90)
    assert not multiprocessing.active_children()  # every worker, replaced ones too, is gone


def test_an_exception_is_the_same_outcome_in_process_and_in_a_worker() -> None:
    items = [1, 6, 2]
    assert executor.run(misbehaving, 2, items, 1) == executor.run(misbehaving, 2, items, 2)


def test_a_sweep_inside_a_worker_runs_in_that_worker() -> None:
    assert executor.run(nested, 2, [1, 5], jobs=2) == [Done([2, 4]), Done([10, 12])]


def test_ctrl_c_stops_the_workers() -> None:
    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGALRM, interrupt)
    signal.setitimer(signal.ITIMER_REAL, 0.5)
    try:
        with pytest.raises(KeyboardInterrupt):
            executor.run(sleepy, 60.0, [1, 2, 3], jobs=2)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    assert not multiprocessing.active_children()


def test_parse_jobs() -> None:
    assert executor.parse_jobs("3") == 3
    assert executor.parse_jobs("auto") == executor.default_jobs() >= 1
    for bad in ("-1", "two", ""):
        with pytest.raises(ValueError):
            executor.parse_jobs(bad)


def test_lint_findings_are_identical_with_one_and_two_jobs() -> None:
    two = parse_selection(TWO)
    runs = [lint_paths([BAY], LintConfig(), manikins=two, jobs=j) for j in (1, 2)]
    assert runs[0].findings  # something to compare
    json = [RENDERERS["json"](r, Path.cwd()) for r in runs]
    assert json[0] == json[1]


def test_a_worker_crash_in_lint_is_one_mt0900_finding(monkeypatch: pytest.MonkeyPatch) -> None:
    """The forked workers inherit the patched pass runner: the small manikin's compile kills
    its worker; the large one's findings are still there."""
    import mtlc.lint.engine as engine

    real = engine.run_motion

    def crash_for_the_small_one(timeline, sink, options):  # type: ignore[no-untyped-def]
        if timeline.manikin.sex == "female":
            os._exit(9)
        return real(timeline, sink, options)

    monkeypatch.setattr(engine, "run_motion", crash_for_the_small_one)
    two = parse_selection(TWO)
    result = lint_paths([BAY], LintConfig(), manikins=two, jobs=2)
    (crash,) = [f for f in result.findings if f.code == "MT0900"]
    assert crash.manikins == ("gb10000_1988:female:5",)
    assert "worker process exited with code 9" in crash.message
    alone = lint_paths([BAY], LintConfig(), manikins=two[1:], jobs=1)
    rest = [f for f in result.findings if f.code != "MT0900"]
    assert [(f.code, f.span, f.message) for f in rest] == [
        (f.code, f.span, f.message) for f in alone.findings
    ]


def test_report_numbers_are_identical_with_one_and_two_jobs() -> None:
    (timeline,) = run_frontend([SHELF]).timelines
    two = parse_selection(TWO)
    one, both = (analyse_task(timeline, two, jobs=j) for j in (1, 2))
    assert one == both and all(m.method == "full" for m in one.manikins)
