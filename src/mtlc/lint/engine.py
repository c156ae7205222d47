"""Lint = front end (once per file) + timing and motion passes per manikin + rules over them.

The sweep: every selected manikin is compiled in full (every motion pass) and every motion
rule runs on it, so a finding for one manikin is exactly what `mtlc compile --manikin` and the
rules say for that manikin, never a guess from a neighbour. The front end runs once per file in
this process and leaves its timelines untimed (the same for every manikin); each is then timed
for each manikin as compile times it (``frontend.time_task``: a walk's steps take the time of
that body's gait, and the task's budget, MT0404, and the motion budget, MT0407, are checked on
that time). The (task, manikin) compiles run through mtlc.executor (``jobs`` worker processes,
the timed timelines shipped to them once), and their findings come back in a fixed order, so
the result is the same whatever the number of jobs. Findings for several manikins merge into
one that names them all.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from mtlc import executor
from mtlc.diagnostics import DiagnosticSink, Severity
from mtlc.frontend import (
    DEFAULT_MOTION_BUDGET,
    FrontendOptions,
    Program,
    run_frontend,
    time_task,
)
from mtlc.lint import suppress
from mtlc.lint.config import LintConfig
from mtlc.lint.findings import Finding, from_diagnostic, merge
from mtlc.lint.manikins import label, parse_selection
from mtlc.lint.rules import RULES
from mtlc.lint.rules.view import make_view
from mtlc.passes import MotionOptions, run_motion
from mtlc.semantics.timeline import ManikinSpec, Timeline

# verify's findings that a lint rule reports with a threshold of the user's, from the same
# figures (docs/lint.md): lint gives the rule's finding, not both
SCREENED_BY = {"MT0512": "MT0604", "MT0513": "MT0603"}
SEVERITY_RANK = {Severity.NOTE: 1, Severity.WARNING: 2, Severity.ERROR: 3}
# what only the motion passes find: without one of these enabled no motion is compiled (the
# passes' own codes, then every motion rule's)
MOTION_CODES = (
    "MT0501",
    "MT0502",
    "MT0503",
    "MT0510",
    "MT0511",
    "MT0512",
    "MT0513",
    "MT0514",
    "MT0515",
    *(rule.code for rule in RULES if rule.on == "motion"),
)


@dataclass
class LintResult:
    findings: list[Finding]
    sources: dict[str, str]
    files: list[Path]
    manikins: tuple[ManikinSpec, ...]
    rules_run: list[str] = field(default_factory=list)

    @property
    def full(self) -> tuple[ManikinSpec, ...]:
        """The manikins compiled in full: every selected one (the reach screen is gone)."""
        return self.manikins

    def failing(self, at: Severity) -> list[Finding]:
        return [f for f in self.findings if SEVERITY_RANK[f.severity] >= SEVERITY_RANK[at]]


def collect_files(paths: list[Path]) -> list[Path]:
    """Files as given; folders walked for *.mtask, sorted, each file once."""
    out: list[Path] = []
    for p in paths:
        found = sorted(p.rglob("*.mtask")) if p.is_dir() else [p]
        out.extend(f for f in found if f not in out)
    return out


def lint_paths(
    paths: list[Path],
    config: LintConfig,
    *,
    manikins: tuple[ManikinSpec, ...] | None = None,
    include_dirs: tuple[Path, ...] = (),
    motion: MotionOptions | None = None,
    motion_budget: float = DEFAULT_MOTION_BUDGET,
    jobs: int | None = None,
) -> LintResult:
    """Lint ``paths`` for each manikin of the selection; ``jobs`` worker processes for the
    compiles (None: one per CPU; 1: in this process)."""
    selection = manikins or parse_selection(config.manikins)
    files = collect_files(paths)
    findings: list[Finding] = []
    sources: dict[str, str] = {}
    roots: list[str] = []
    timed: list[tuple[Timeline, ManikinSpec]] = []
    for path in files:
        options = FrontendOptions(
            include_dirs=include_dirs, motion_budget=motion_budget, timed=False
        )
        program = run_frontend([path], options)
        sources.update(program.sources)
        roots.extend(str(m.tree.path) for m in program.roots)
        findings.extend(from_diagnostic(d) for d in program.diagnostics)
        if program.sink.has_errors:
            continue  # rules read checked code only
        findings.extend(_program_rules(program, config))
        found, compiled = time_for_sweep(program.timelines, selection, motion_budget)
        findings.extend(found)
        if any(config.enabled(c) for c in MOTION_CODES):
            timed.extend(compiled)
    if timed:
        sweep = Sweep(tuple(t for t, _ in timed), config, motion or MotionOptions())
        findings.extend(run_sweep(sweep, [spec for _, spec in timed], jobs))
    # errors cannot be deselected: code that does not compile is never 'clean'
    findings = [f for f in findings if config.enabled(f.code) or f.severity is Severity.ERROR]
    marks = [s for file in dict.fromkeys(roots) for s in suppress.scan(file, sources.get(file, ""))]
    findings = suppress.apply(
        findings, marks, report_unused=config.enabled("MT0606"), checked=config.enabled
    )
    order = [label(m) for m in selection]
    return LintResult(
        merge(findings, order),
        sources,
        files,
        selection,
        [r.code for r in RULES if config.enabled(r.code)],
    )


def time_for_sweep(
    timelines: list[Timeline], selection: tuple[ManikinSpec, ...], motion_budget: float
) -> tuple[list[Finding], list[tuple[Timeline, ManikinSpec]]]:
    """Each untimed timeline timed for each manikin of ``selection`` as `mtlc compile
    --manikin` times it (``frontend.time_task``): the findings of that (MT0404, MT0407) for
    the manikin, and the (timeline, manikin) pairs to compile, in task then selection order
    (a task past the motion budget for a manikin is not compiled for it)."""
    findings: list[Finding] = []
    out: list[tuple[Timeline, ManikinSpec]] = []
    for timeline in timelines:
        for spec in selection:
            sink = DiagnosticSink()
            timed = time_task(timeline, spec, motion_budget, sink)
            findings.extend(from_diagnostic(d, label(spec)) for d in sink.sorted())
            if timed is not None:
                out.append((timed, spec))
    return findings, out


def _program_rules(program: Program, config: LintConfig) -> list[Finding]:
    out: list[Finding] = []
    for rule in RULES:
        if rule.on == "program" and config.enabled(rule.code):
            out.extend(rule.check(program))  # type: ignore[arg-type]
    return out


@dataclass(frozen=True)
class Sweep:
    """What every compile of a lint run shares, shipped to each worker once."""

    timelines: tuple[Timeline, ...]  # each timed for the manikin it is compiled for
    config: LintConfig
    options: MotionOptions


def run_sweep(sweep: Sweep, specs: list[ManikinSpec], jobs: int | None = None) -> list[Finding]:
    """Every timeline of the sweep compiled in full for its manikin (``specs``, one each) and
    its motion rules, through the executor; the findings in the sweep's order. A compile that
    raised or whose worker died is one MT0900 finding for that task and manikin; the others
    go on."""
    items = list(enumerate(specs))
    out: list[Finding] = []
    for (i, spec), outcome in zip(items, executor.run(lint_one, sweep, items, jobs), strict=True):
        if isinstance(outcome, executor.Done):
            out.extend(outcome.value)
        else:
            out.append(_internal_error(sweep.timelines[i], spec, outcome.message))
    return out


def lint_one(sweep: Sweep, item: tuple[int, ManikinSpec]) -> list[Finding]:
    """One task compiled for one manikin, and the motion rules over it (runs in a worker; a
    bug in a pass is the executor's Failed, one MT0900 finding in run_sweep)."""
    index, spec = item
    timeline = sweep.timelines[index]
    sink = DiagnosticSink()
    ir = run_motion(timeline, sink, sweep.options)  # timed for ``spec`` (time_for_sweep)
    out = [
        from_diagnostic(d, label(spec))
        for d in sink.sorted()
        if not sweep.config.enabled(SCREENED_BY.get(d.code, ""))  # lint's MT0603/MT0604 instead
    ]
    view = make_view(ir, label(spec), sweep.config, timeline)
    if view is None:
        return out
    for rule in RULES:
        if rule.on == "motion" and sweep.config.enabled(rule.code):
            out.extend(rule.check(view))  # type: ignore[arg-type]
    return out


def _internal_error(timeline: Timeline, spec: ManikinSpec, why: str) -> Finding:
    message = f"internal error compiling task `{timeline.task}`: {why}"
    return Finding(
        "MT0900",
        message,
        timeline.span,
        help="this is a bug in mtlc; `mtlc compile` with MTLC_DEBUG=1 shows the trace",
        manikins=(label(spec),),
        details=(message,),
    )
