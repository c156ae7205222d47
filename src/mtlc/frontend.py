"""The front end as an ordered list of passes: text → modules → scopes → checked → timelines.

Each pass takes the Program and returns it with its own stage filled in; the order is FRONTEND
below and nowhere else. The motion passes (IR lowering and after) continue from the timelines.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mtlc.diagnostics import Diagnostic, DiagnosticSink
from mtlc.semantics import schedule
from mtlc.semantics.check import Checker, check_recursion
from mtlc.semantics.expand import DEFAULT_BUDGET, Expander
from mtlc.semantics.modules import LoadedModule, ModuleLoader
from mtlc.semantics.scopes import Scope, build_scopes
from mtlc.semantics.timeline import ManikinSpec, Timeline
from mtlc.syntax import ast
from mtlc.syntax.gcpause import no_collections

# seconds of motion a task may take (MT0407). The motion passes cost memory and time in
# proportion to the motion's length (about 8 MB a minute of standing in compile and in lint,
# more for a walk, at the default rates: docs/passes.md, "Memory"): the budget stops a task that would take gigabytes
# before its frames are built. Raised with --motion-budget.
DEFAULT_MOTION_BUDGET = 15 * 60.0


DURATION_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0}


def motion_budget(text: str) -> float:
    """`--motion-budget 45min`: a duration with its unit (s, min or h), as in the language."""
    number = text.rstrip("minhs ")
    unit = text[len(number) :].strip()
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if unit not in DURATION_UNITS or not math.isfinite(value):
        raise argparse.ArgumentTypeError("expected a duration with its unit, e.g. 90s, 45min or 2h")
    if value <= 0:
        raise argparse.ArgumentTypeError("must be more than 0")
    return value * DURATION_UNITS[unit]


def add_motion_budget(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--motion-budget", type=motion_budget, default=DEFAULT_MOTION_BUDGET, metavar="DURATION",
        help="longest motion a task may have, e.g. 45min or 2h "
        f"(default {DEFAULT_MOTION_BUDGET / 60:g}min; memory grows with it)",
    )  # fmt: skip


@dataclass(frozen=True)
class FrontendOptions:
    include_dirs: tuple[Path, ...] = ()
    expansion_budget: int = DEFAULT_BUDGET
    motion_budget: float = DEFAULT_MOTION_BUDGET  # seconds of motion per task
    manikin: ManikinSpec | None = None
    expand: bool = True
    # False: the timelines as expanded, the same for every manikin and not yet timed for one
    # (lint and report time them for each manikin they sweep, with ``time_task``)
    timed: bool = True
    # scene sites at other positions (metres), by name: what `mtlc serve` does when one is dragged
    site_overrides: tuple[tuple[str, tuple[float, float, float]], ...] = ()


@dataclass
class Program:
    paths: list[Path]
    options: FrontendOptions
    sink: DiagnosticSink = field(default_factory=DiagnosticSink)
    loader: ModuleLoader | None = None
    roots: list[LoadedModule] = field(default_factory=list)
    scopes: dict[int, Scope] = field(default_factory=dict)
    checker: Checker | None = None
    timelines: list[Timeline] = field(default_factory=list)

    @property
    def modules(self) -> list[LoadedModule]:
        return list(self.loader.modules.values()) if self.loader else []

    @property
    def sources(self) -> dict[str, str]:
        return self.loader.sources if self.loader else {}

    @property
    def diagnostics(self) -> list[Diagnostic]:
        return self.sink.sorted()

    @property
    def model_files(self) -> list[Path]:
        """The model files the scenes name (whether they could be read or not)."""
        return list(self.checker.model_files) if self.checker else []


def load_modules(program: Program) -> Program:
    program.loader = ModuleLoader(list(program.options.include_dirs), program.sink)
    for path in program.paths:
        module = program.loader.load_root(path)
        if module is not None and module not in program.roots:
            program.roots.append(module)
    return program


def collect_scopes(program: Program) -> Program:
    program.scopes = build_scopes(program.modules, program.sink)
    return program


def check_definitions(program: Program) -> Program:
    program.checker = Checker(program.sink)
    for module in program.modules:
        program.checker.check_module(program.scopes[id(module)])
    return program


def check_call_cycles(program: Program) -> Program:
    assert program.checker is not None
    check_recursion(program.checker.edges, program.sink)
    return program


def expand_tasks(program: Program) -> Program:
    if not program.options.expand or program.sink.has_errors:
        return program  # expansion evaluates checked code only
    assert program.checker is not None
    expander = Expander(
        program.sink,
        program.scopes,
        program.checker.resolved,
        program.checker.callees,
        program.options.expansion_budget,
        program.options.manikin,
        dict(program.options.site_overrides),
        program.checker.meshes,
    )
    for module in program.roots:
        scope = program.scopes[id(module)]
        for decl in module.tree.decls:
            if isinstance(decl, ast.Task) and scope.own.get(decl.name) is not None:
                timeline = expander.expand_task(decl, scope)
                if timeline is not None:
                    program.timelines.append(timeline)
    return program


def time_tasks(program: Program) -> Program:
    """Each timeline timed for its manikin (the task's, or the options' override)."""
    if not program.options.timed:
        return program
    timed = (
        time_task(t, t.manikin, program.options.motion_budget, program.sink)
        for t in program.timelines
    )
    program.timelines = [t for t in timed if t is not None]
    return program


def time_task(
    timeline: Timeline, spec: ManikinSpec, motion_budget: float, sink: DiagnosticSink
) -> Timeline | None:
    """The expanded ``timeline`` timed for manikin ``spec`` (``schedule.for_manikin``: its
    walks' step time depends on the body) and its time checked: the task's `budget` (MT0404)
    and the motion budget (MT0407, and then None: no motion is compiled). Every command gets a
    manikin's timeline here, compile for one manikin, lint and report for each they sweep, so a
    manikin's motion and these findings are the same whichever command asks."""
    timed = schedule.for_manikin(timeline, spec)
    schedule.check_budget(timed, sink)
    return timed if within_motion_budget(timed, motion_budget, sink) else None


def format_duration(seconds: float) -> str:
    """`45 s`, `12 min 2 s`, `2 h 0 min`: a motion's length as a person reads it."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, secs = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min" + (f" {secs} s" if secs else "")
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min"


def within_motion_budget(timeline: Timeline, budget: float, sink: DiagnosticSink) -> bool:
    """False (and MT0407 reported) when the task's motion is longer than ``budget`` seconds.

    Checked on the timeline, before any frame exists: the motion passes' memory grows with the
    motion's length. Reported at the line of the task whose primitive first runs past the
    budget (the earliest-starting one that ends after it).
    """
    if not timeline.duration > budget:
        return True
    over = min((p for p in timeline.primitives if p.end > budget), key=lambda p: p.start)
    limit = format_duration(budget)
    sink.report(
        "MT0407",
        f"task `{timeline.task}` has {format_duration(timeline.duration)} of motion, more than "
        f"the motion budget of {limit}",
        over.origin,
        help="split the task, shorten this step, or raise the limit with --motion-budget "
        "(e.g. --motion-budget 2h)",
        notes=(
            "the motion passes need memory in proportion to the motion's length (docs/passes.md); "
            f"the default limit is {format_duration(DEFAULT_MOTION_BUDGET)}",
        ),
    )
    return False


FRONTEND: list[tuple[str, Callable[[Program], Program]]] = [
    ("load", load_modules),
    ("scopes", collect_scopes),
    ("check", check_definitions),
    ("cycles", check_call_cycles),
    ("expand", expand_tasks),
    ("time", time_tasks),
]


def run_frontend(paths: list[Path], options: FrontendOptions | None = None) -> Program:
    program = Program(list(paths), options or FrontendOptions())
    with no_collections():  # tokens, nodes and primitives: many young objects, no cycles
        for _name, stage in FRONTEND:
            program = stage(program)
    return program
