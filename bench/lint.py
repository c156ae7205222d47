"""`mtlc lint --manikins all` against one manikin, and against full compiles of each manikin.

    python bench/lint.py [--jobs N] [--validate] [--passes] [FILE ...]

Default files: the examples and tests/data/sweep/*.mtask (16 procedures written for issue 18).
For each file, in this process (imports excluded):

- ``1 (s)``: wall time of `lint` for one manikin in this process (`--jobs 1`), the mean over the
  14 GB 10000-88 manikins (each linted alone), and ``cpu1``, its CPU time (mean);
- ``14 (s)``: wall time of `lint --manikins all --jobs N` (worker processes, default one per CPU)
  and ``cpu14``, the CPU time it used in this process and its workers;
- ``14/1``: the wall-time ratio, the goal (issue 18) is < 3; ``cpu``: the CPU-time ratio (the
  work done; on an idle machine the wall ratio is about ``cpu`` / N).

``--validate`` compares, per (manikin, finding), what `lint --manikins all` reports with what
linting that manikin alone (a full compile in this process) reports: agree / missed (only the
single compile has it) / extra (only the sweep has it). The goal is 0 missed and 0 extra.
``--passes`` prints where one compile's time goes, per motion pass (one manikin per file).
Wall times on a shared machine vary with the load: the CPU column and the ratio matter more.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from pathlib import Path

from mtlc.diagnostics import DiagnosticSink
from mtlc.executor import default_jobs
from mtlc.frontend import run_frontend
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.engine import LintResult
from mtlc.lint.manikins import EXTREMES, all_manikins, label
from mtlc.passes import MOTION_PASSES, MotionOptions, PassContext, lower
from mtlc.semantics import schedule

ROOT = Path(__file__).resolve().parents[1]
GOAL_RATIO = 3.0

Key = tuple[str, int, int, str, str]  # code, line, column, manikin, that manikin's message


def cpu_seconds() -> float:
    """CPU time of this process and of its waited-for children (the workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def keys(result: LintResult) -> set[Key]:
    """Each (finding, manikin) pair of a lint result; findings that name no manikin (the front
    end's, unused definitions) do not depend on the sweep and are left out."""
    return {
        (f.code, f.span.line, f.span.column, m, d)
        for f in result.findings
        for m, d in zip(f.manikins, f.details, strict=True)
    }


def pass_times(path: Path) -> dict[str, float]:
    """Seconds per motion pass for one compile (female p5) of each task of ``path``."""
    out: dict[str, float] = {}
    for timeline in run_frontend([path]).timelines:
        ctx = PassContext(DiagnosticSink(), MotionOptions())
        t0 = time.perf_counter()
        ir = lower(schedule.for_manikin(timeline, EXTREMES[0]))
        out["lower"] = out.get("lower", 0.0) + time.perf_counter() - t0
        for name, motion_pass in MOTION_PASSES:
            t0 = time.perf_counter()
            ir = motion_pass(ir, ctx)
            out[name] = out.get(name, 0.0) + time.perf_counter() - t0
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("files", nargs="*", type=Path)
    parser.add_argument("--jobs", type=int, default=default_jobs())
    parser.add_argument("--validate", action="store_true")
    parser.add_argument("--passes", action="store_true")
    args = parser.parse_args()
    files = args.files or [
        *sorted((ROOT / "examples").glob("*.mtask")),
        *sorted((ROOT / "tests/data/sweep").glob("*.mtask")),
    ]
    manikins = all_manikins()
    config = LintConfig()
    lint_paths(files[:1], config, manikins=EXTREMES[:1], jobs=1)  # warm caches (tables, grammar)
    print(f"{len(manikins)} manikins, {args.jobs} jobs, {os.cpu_count()} CPUs")
    head = (
        f"{'file':28} {'1 (s)':>7} {'cpu1':>6} {'14 (s)':>7} {'cpu14':>7} {'14/1':>6} {'goal':>5}"
        f" {'cpu':>6}"
    )
    if args.validate:
        head += f" {'agree':>6} {'missed':>6} {'extra':>6}"
    print(head)
    print("-" * len(head))
    sums = [0.0, 0.0, 0.0, 0.0]
    table = [0, 0, 0]
    for path in files:
        singles: set[Key] = set()
        alone = alone_cpu = 0.0
        for spec in manikins:
            c0, t0 = cpu_seconds(), time.perf_counter()
            result = lint_paths([path], config, manikins=(spec,), jobs=1)
            alone += time.perf_counter() - t0
            alone_cpu += cpu_seconds() - c0
            singles |= keys(result)
        one, one_cpu = alone / len(manikins), alone_cpu / len(manikins)
        c0, t0 = cpu_seconds(), time.perf_counter()
        swept = lint_paths([path], config, manikins=manikins, jobs=args.jobs)
        many, cpu = time.perf_counter() - t0, cpu_seconds() - c0
        sums = [a + b for a, b in zip(sums, (one, one_cpu, many, cpu), strict=True)]
        row = (
            f"{path.stem[:28]:28} {one:7.2f} {one_cpu:6.2f} {many:7.2f} {cpu:7.2f} "
            f"{many / one:6.2f} {'<3':>5} {cpu / one_cpu:6.2f}"
        )
        if args.validate:
            found = keys(swept)
            counts = [len(found & singles), len(singles - found), len(found - singles)]
            table = [a + b for a, b in zip(table, counts, strict=True)]
            row += " {:6d} {:6d} {:6d}".format(*counts)
            for key in sorted(singles ^ found):
                print(f"    {'missed' if key in singles else 'extra'}: {key}")
        print(row)
    print("-" * len(head))
    total = (
        f"{'all files':28} {sums[0]:7.2f} {sums[1]:6.2f} {sums[2]:7.2f} {sums[3]:7.2f} "
        f"{sums[2] / sums[0]:6.2f} {'<3':>5} {sums[3] / sums[1]:6.2f}"
    )
    if args.validate:
        total += " {:6d} {:6d} {:6d}".format(*table)
    print(total)
    ratio = sums[2] / sums[0]
    verdict = "met" if ratio < GOAL_RATIO else "NOT met"
    print(f"\n14 manikins / one manikin, wall: {ratio:.2f}x (goal < {GOAL_RATIO:.0f}x: {verdict})")
    print(f"14 manikins / one manikin, CPU: {sums[3] / sums[1]:.2f}x (the work; no sharing: 14)")
    if args.validate:
        ok = "met" if table[1] == table[2] == 0 else "NOT met"
        print(
            f"agree/missed/extra {table[0]}/{table[1]}/{table[2]} (goal: 0 missed, 0 extra: {ok})"
        )
    if args.passes:
        print(f"\nwhere one compile's time goes ({label(EXTREMES[0])}), seconds per pass:")
        per = {p.stem: pass_times(p) for p in files}
        names = list(next(iter(per.values())))
        print(f"{'file':28} " + " ".join(f"{n[:8]:>8}" for n in names))
        for stem, times in per.items():
            print(f"{stem[:28]:28} " + " ".join(f"{times.get(n, 0.0):8.2f}" for n in names))


if __name__ == "__main__":
    main()
