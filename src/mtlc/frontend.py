"""The front end as an ordered list of passes: text → modules → scopes → checked → timelines.

Each pass takes the Program and returns it with its own stage filled in; the order is FRONTEND
below and nowhere else. The motion passes (IR lowering and after) continue from the timelines.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mtlc.diagnostics import Diagnostic, DiagnosticSink
from mtlc.semantics.check import Checker, check_recursion
from mtlc.semantics.expand import DEFAULT_BUDGET, Expander
from mtlc.semantics.modules import LoadedModule, ModuleLoader
from mtlc.semantics.scopes import Scope, build_scopes
from mtlc.semantics.timeline import ManikinSpec, Timeline
from mtlc.syntax import ast


@dataclass(frozen=True)
class FrontendOptions:
    include_dirs: tuple[Path, ...] = ()
    expansion_budget: int = DEFAULT_BUDGET
    manikin: ManikinSpec | None = None
    expand: bool = True
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
    )
    for module in program.roots:
        scope = program.scopes[id(module)]
        for decl in module.tree.decls:
            if isinstance(decl, ast.Task) and scope.own.get(decl.name) is not None:
                timeline = expander.expand_task(decl, scope)
                if timeline is not None:
                    program.timelines.append(timeline)
    return program


FRONTEND: list[tuple[str, Callable[[Program], Program]]] = [
    ("load", load_modules),
    ("scopes", collect_scopes),
    ("check", check_definitions),
    ("cycles", check_call_cycles),
    ("expand", expand_tasks),
]


def run_frontend(paths: list[Path], options: FrontendOptions | None = None) -> Program:
    program = Program(list(paths), options or FrontendOptions())
    for _name, stage in FRONTEND:
        program = stage(program)
    return program
