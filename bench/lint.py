"""`mtlc lint` timing: every example with one manikin, the default two and all 14.

    python bench/lint.py [--repeat 3] [--validate]

Seconds per file, in process (imports excluded), best of ``--repeat`` runs. Target (issue 6):
all 14 GB 10000-88 manikins in less than 3 times the time of one. ``--validate`` also compiles
every screened manikin in full and compares the reach screen's MT0501 findings (which task line,
which hand, which site) with the motion passes' own: agreement, misses and extras.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.engine import envelope, nearest
from mtlc.lint.manikins import EXTREMES, all_manikins
from mtlc.lint.rules.reach import screen
from mtlc.passes import run_motion
from mtlc.semantics.timeline import ManikinSpec, Timeline

ROOT = Path(__file__).resolve().parents[1]
ONE = (EXTREMES[0],)


def best_of(repeat: int, path: Path, manikins: tuple[ManikinSpec, ...]) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        lint_paths([path], LintConfig(), manikins=manikins)
        best = min(best, time.perf_counter() - t0)
    return best


def _key(message: str, line: int) -> tuple[int, str]:
    return line, message.rsplit(": ", 1)[0]


def compile_or_none(timeline: Timeline, spec: ManikinSpec, sink: DiagnosticSink) -> MotionIR | None:
    """A full compile, or None when a pass fails (passes under edit elsewhere)."""
    try:
        return run_motion(dataclasses.replace(timeline, manikin=spec), sink)
    except Exception:
        return None


def validate(path: Path) -> tuple[int, int, int]:
    """(agreeing, missed, extra) screened (manikin, goal) pairs against full compiles; manikins
    whose full compile fails are left out."""
    program = run_frontend([path])
    selection = all_manikins()
    full = envelope(selection)
    agree = missed = extra = 0
    for timeline in program.timelines:
        compiled = {}
        for spec in full:
            ir = compile_or_none(timeline, spec, DiagnosticSink())
            if ir is not None:
                compiled[spec] = ir
        for spec in selection:
            sink = DiagnosticSink()
            if spec in full or not compiled or compile_or_none(timeline, spec, sink) is None:
                continue
            near = compiled[nearest(spec, tuple(compiled))]
            screened = {_key(f.message, f.span.line) for f in screen(near, spec)}
            truth = {_key(d.message, d.span.line) for d in sink.sorted() if d.code == "MT0501"}
            agree += len(screened & truth)
            missed += len(truth - screened)
            extra += len(screened - truth)
    return agree, missed, extra


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--validate", action="store_true")
    args = parser.parse_args()
    examples = sorted((ROOT / "examples").glob("*.mtask"))
    lint_paths(examples[:1], LintConfig(), manikins=ONE)  # warm caches (tables, grammar)
    header = f"{'file':32} {'1 (s)':>7} {'2 (s)':>7} {'14 (s)':>7} {'14/1':>6}"
    print(header + ("  screen agree/missed/extra" if args.validate else ""))
    print("-" * len(header))
    totals = [0.0, 0.0, 0.0]
    for path in examples:
        times = [best_of(args.repeat, path, m) for m in (ONE, EXTREMES, all_manikins())]
        totals = [a + b for a, b in zip(totals, times, strict=True)]
        row = f"{path.stem:32} {times[0]:7.3f} {times[1]:7.3f} {times[2]:7.3f} {times[2] / times[0]:6.2f}"
        if args.validate:
            row += "  {}/{}/{}".format(*validate(path))
        print(row)
    n = len(examples)
    print("-" * len(header))
    print(
        f"{'per file (mean)':32} {totals[0] / n:7.3f} {totals[1] / n:7.3f} {totals[2] / n:7.3f} "
        f"{totals[2] / totals[0]:6.2f}"
    )
    print(f"\nall 14 manikins / one manikin: {totals[2] / totals[0]:.2f}x (target < 3x)")


if __name__ == "__main__":
    main()
