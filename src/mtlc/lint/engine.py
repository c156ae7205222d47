"""Lint = front end (once per file) + motion passes per manikin + rules over the results.

The sweep: the selection's extremes by stature (all of it when it has two manikins or fewer)
are compiled in full and every motion rule runs on them; the manikins between are screened for
reach (MT0501) by one batched IK call per hand (mtlc.lint.rules.reach), which costs a small
fraction of a compile. Findings for several manikins merge into one that names them all.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from mtlc.diagnostics import DiagnosticSink, Severity
from mtlc.frontend import DEFAULT_MOTION_BUDGET, FrontendOptions, Program, run_frontend
from mtlc.lint import suppress
from mtlc.lint.config import LintConfig
from mtlc.lint.findings import Finding, from_diagnostic, merge
from mtlc.lint.manikins import label, parse_selection
from mtlc.lint.rules import RULES
from mtlc.lint.rules.reach import screen, stature
from mtlc.lint.rules.view import make_view
from mtlc.passes import MotionOptions, run_motion
from mtlc.semantics.timeline import ManikinSpec, Timeline

# verify's findings that a lint rule reports with a threshold of the user's, from the same
# figures (docs/lint.md): lint gives the rule's finding, not both
SCREENED_BY = {"MT0512": "MT0604", "MT0513": "MT0603"}
SEVERITY_RANK = {Severity.NOTE: 1, Severity.WARNING: 2, Severity.ERROR: 3}
# what only the motion passes find: without one of these enabled no motion is compiled
MOTION_CODES = (
    "MT0501",
    "MT0502",
    "MT0503",
    "MT0510",
    "MT0511",
    "MT0512",
    "MT0513",
    "MT0514",
    "MT0603",
    "MT0604",
    "MT0605",
    "MT0607",
    "MT0608",
    "MT0609",
)


@dataclass
class LintResult:
    findings: list[Finding]
    sources: dict[str, str]
    files: list[Path]
    manikins: tuple[ManikinSpec, ...]
    full: tuple[ManikinSpec, ...]  # compiled in full; the others were screened for reach
    rules_run: list[str] = field(default_factory=list)

    def failing(self, at: Severity) -> list[Finding]:
        return [f for f in self.findings if SEVERITY_RANK[f.severity] >= SEVERITY_RANK[at]]


def collect_files(paths: list[Path]) -> list[Path]:
    """Files as given; folders walked for *.mtask, sorted, each file once."""
    out: list[Path] = []
    for p in paths:
        found = sorted(p.rglob("*.mtask")) if p.is_dir() else [p]
        out.extend(f for f in found if f not in out)
    return out


def envelope(manikins: tuple[ManikinSpec, ...]) -> tuple[ManikinSpec, ...]:
    """The smallest and the largest by stature (in selection order), or all of two or fewer."""
    if len(manikins) <= 2:
        return manikins
    small = min(manikins, key=stature)
    large = max(manikins, key=stature)
    return tuple(m for m in manikins if m in (small, large))


def nearest(spec: ManikinSpec, full: tuple[ManikinSpec, ...]) -> ManikinSpec:
    return min(full, key=lambda m: abs(stature(m) - stature(spec)))


def lint_paths(
    paths: list[Path],
    config: LintConfig,
    *,
    manikins: tuple[ManikinSpec, ...] | None = None,
    include_dirs: tuple[Path, ...] = (),
    motion: MotionOptions | None = None,
    motion_budget: float = DEFAULT_MOTION_BUDGET,
) -> LintResult:
    selection = manikins or parse_selection(config.manikins)
    full = envelope(selection)
    files = collect_files(paths)
    findings: list[Finding] = []
    sources: dict[str, str] = {}
    roots: list[str] = []
    for path in files:
        options = FrontendOptions(include_dirs=include_dirs, motion_budget=motion_budget)
        program = run_frontend([path], options)
        sources.update(program.sources)
        roots.extend(str(m.tree.path) for m in program.roots)
        findings.extend(from_diagnostic(d) for d in program.diagnostics)
        if program.sink.has_errors:
            continue  # rules read checked code only
        findings.extend(_program_rules(program, config))
        if not any(config.enabled(c) for c in MOTION_CODES):
            continue
        for timeline in program.timelines:
            findings.extend(_sweep(timeline, selection, full, config, motion or MotionOptions()))
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
        full,
        [r.code for r in RULES if config.enabled(r.code)],
    )


def _program_rules(program: Program, config: LintConfig) -> list[Finding]:
    out: list[Finding] = []
    for rule in RULES:
        if rule.on == "program" and config.enabled(rule.code):
            out.extend(rule.check(program))  # type: ignore[arg-type]
    return out


def _sweep(
    timeline: Timeline,
    selection: tuple[ManikinSpec, ...],
    full: tuple[ManikinSpec, ...],
    config: LintConfig,
    options: MotionOptions,
) -> list[Finding]:
    out: list[Finding] = []
    compiled = {}
    for spec in full:
        sink = DiagnosticSink()
        try:
            ir = run_motion(dataclasses.replace(timeline, manikin=spec), sink, options)
        except Exception as exc:  # a bug in a pass: one finding, and the other tasks go on
            out.append(_internal_error(timeline, spec, exc))
            continue
        compiled[spec] = ir
        out.extend(
            from_diagnostic(d, label(spec))
            for d in sink.sorted()
            if not config.enabled(SCREENED_BY.get(d.code, ""))
        )
        view = make_view(ir, label(spec), config, timeline)
        if view is None:
            continue
        for rule in RULES:
            if rule.on == "motion" and config.enabled(rule.code):
                out.extend(rule.check(view))  # type: ignore[arg-type]
    if config.enabled("MT0501"):
        for spec in selection:
            if spec not in full and compiled:
                out.extend(screen(compiled[nearest(spec, tuple(compiled))], spec))
    return out


def _internal_error(timeline: Timeline, spec: ManikinSpec, exc: Exception) -> Finding:
    message = f"internal error compiling task `{timeline.task}`: {type(exc).__name__}: {exc}"
    return Finding(
        "MT0900",
        message,
        timeline.span,
        help="this is a bug in mtlc; `mtlc compile` with MTLC_DEBUG=1 shows the trace",
        manikins=(label(spec),),
        details=(message,),
    )
